"""Training-side tools of relight_rt (PyTorch): networks, data rendering, training, export.

Run from a checkout as ``python -m export COMMAND ...``. Not part of the wheel.
"""
