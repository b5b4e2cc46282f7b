"""The version, in one place (the package face and the build-info metric read it)."""

__version__ = "0.1.0"
