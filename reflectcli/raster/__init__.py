"""The numba rasterizer shared by every technique for the non-mirror part of the image."""
