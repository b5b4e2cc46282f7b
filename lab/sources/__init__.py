"""Where the corpus's windows come from: Tennessee Eastman runs through tep-studio (``tep``,
``tep_plan``), the realistic generator (``realistic``), the plant records, shared TEP runs
and single cases (``records``), the named scenarios (``scenarios``)."""
