"""Runs cut into the windows the corpus keeps, one view per sample time (``tep``)."""
