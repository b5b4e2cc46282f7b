"""From one window to one :class:`~stiction.Assessment`: the quality gates
(:mod:`.quality`, :mod:`.responding`), every registered detector (:mod:`.evidence`), the
learned decision over what they saw (:mod:`.features`, :mod:`.model`), the sizing and the
reason (:mod:`.reasons`), assembled by :func:`.analyze.analyze`. The weighted vote it
replaced (:mod:`.combine`, :mod:`.weights`) stays as the benchmarks' baseline."""
