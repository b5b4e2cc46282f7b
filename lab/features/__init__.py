"""The rows the decision reads: each window analysed and turned into its features
(``rows``)."""
