"""The reliability battery's cases, one module per kind of input (see ``docs/scripts/battery.py``)."""
