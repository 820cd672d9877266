"""The GPU training path: a compact bank of posed people, a plain-PyTorch renderer of stage-1 samples, and
``python -m export gpu-train`` (render and train on one CUDA machine until a deadline)."""
