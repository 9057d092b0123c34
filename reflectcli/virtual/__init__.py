"""Virtual objects for curved reflectors (Ofek & Rappoport): for each reflected scene vertex,
a virtual vertex whose ordinary rasterization looks like its reflection."""
