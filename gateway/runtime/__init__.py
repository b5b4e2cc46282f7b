"""The asyncio shell: :mod:`.poller` (one task per device), :mod:`.scheduler` (analysis in a
process pool), :mod:`.reload` (a config -> runtime, with carry-over from the old one),
:mod:`.gateway` (assembly and life cycle), :mod:`.service` (signals, sd_notify, watchdog) and
:mod:`.sdnotify`."""
