"""Benchmarks: ``python -m bench`` (``make bench``) runs every module listed in
:data:`bench.__main__.MODULES`; each has a ``main()`` that prints its figures."""
