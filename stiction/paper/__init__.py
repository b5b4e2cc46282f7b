"""He & Wang (2014): the rows of its Tables 4-9 (:mod:`.tables`) and their reproduction
(:mod:`.reproduce`: simulate each case with :mod:`stiction.scenarios`, analyse it with
:func:`stiction.analyze`, compare)."""
