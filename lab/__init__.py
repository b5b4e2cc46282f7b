"""The lab: the pipeline that makes the shipped decision (stiction/diagnosis/model.json),
from the development corpus to the export. Development tooling: it needs the ``bench``
extra, and nothing of stiction/, gateway/ or plcsim/ imports it.

Its rooms, from the bottom up (each imports only those below it; tests/test_layering.py
checks it; docs/architecture.md draws them):

=========  ================================================================================
ground     ``_types`` (Window, PlantRun, the sources and cause classes, the folds) and
           ``_cache`` (where the caches live, their pickles)
sources    what the windows come from: Tennessee Eastman runs via tep-studio (``tep``,
           ``tep_plan``), the realistic generator, the plant records and shared TEP runs
           (``records``), the named scenarios
windows    the TEP runs cut into views and reduced, cached per run (``tep``)
labels     each window's cause class (``rules``, ``tep``) and the labelled corpus
           (``corpus``)
features   the rows the decision reads (``rows``: analysed windows, cached)
training   the fit, the folds, the thresholds (``fit``), the reports (``report``), the
           weighted vote's calibration (``calibrate``)
export     model.json (``model``: written and checked against scikit-learn) and
           weights.py (``weights``)
commands   ``python -m lab corpus | train [--write] | calibrate [--write]`` (``commands``,
           run by ``__main__``)
=========  ================================================================================
"""
