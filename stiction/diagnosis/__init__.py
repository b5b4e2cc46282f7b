"""From one window to one :class:`~stiction.Assessment`: the quality gates
(:mod:`.quality`, :mod:`.responding`), every registered detector (:mod:`.evidence`), the
combination of their votes (:mod:`.combine`, :mod:`.weights`), the sizing and the reason
(:mod:`.reasons`), assembled by :func:`.analyze.analyze`."""
