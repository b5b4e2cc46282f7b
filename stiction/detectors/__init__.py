"""The published stiction tests, one module each, all behind one interface (:mod:`.base`:
a :class:`~.base.Window` in, an :class:`~stiction.Evidence` out), listed in
:mod:`.registry`. A detector never imports another detector nor the diagnosis."""
