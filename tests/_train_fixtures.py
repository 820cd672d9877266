"""Tiny synthetic data for the training/evaluation tests: re-exported from :mod:`export.toy_data`."""

from export.toy_data import make_lights, make_photos, make_samples, sh_basis, sphere, sphere_transport

__all__ = ["make_lights", "make_photos", "make_samples", "sh_basis", "sphere", "sphere_transport"]
