"""Pixels: the one image intake and its writers, EXIF, sRGB, the guided filter, compositing, foreground colours,
matte edges, optical flow, the crop to the network's square, square regions, EXR."""
