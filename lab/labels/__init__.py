"""Each window's cause class, measured from the data (``rules``, ``tep``), and the labelled
corpus every later room reads (``corpus``)."""
