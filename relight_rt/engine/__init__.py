"""What everything else runs on: the error type, environment variables, limits on what is loaded, atomic files,
the runtime configuration, the model contract, ONNX sessions and their graph cache, the CUDA chain."""
