"""Synthetic data for relight_rt: bodies, garments, ray-cast transport, lights and photos."""
