"""Lights: the SH basis and shading, presets, where a light comes from (LightSpec), light files, environment maps,
light from a background photo, the light preview sheet, exposure."""
