"""What the lab ships into stiction/: model.json (``model``) and weights.py (``weights``)."""
