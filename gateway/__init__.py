"""The stiction gateway daemon: polls PLCs, analyses loop windows, publishes results."""

__version__ = "0.1.0"
