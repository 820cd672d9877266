"""Video: the streaming video job, frame sources and sinks, the stabiliser, temporal metrics."""
