"""Virtual objects for curved reflectors (Ofek & Rappoport): for each reflected scene vertex,
a virtual vertex whose ordinary rasterization looks like its reflection.

One idea per module, in the order a frame uses them (reflectcli/techniques/virtual/):
    reflected     what a reflector reflects, tessellated (cached per geometry state)
    tessellation  splitting triangles on a shared barycentric grid
    dispatch      the method per reflector, and its parts with their vertex functions
    circle        exact method for spheres and cylinders, blocks of points side by side
    direct        exact method for extrusions of a profile
    mesh          a reflector's triangle soup welded into an indexed mesh
    convexity     convex / concave / crease parts of a mesh reflector
    shape         per reflector shape, once: mesh, parts, boundary edges (cached)
    view          per shape and view: hidden map, reflection-ray grid, tiles (cached)
    part          one part's virtual vertices: explosion maps, then the refinement
    parts         all parts of a reflector stage by stage, each stage one region for all
    explosion     explosion maps and their lookup (numba), built where looked up
    mapfill       the maps' texel fills: faces, extensions, nearest filled texel (numba)
    refine        Gauss-Newton on the reflector's pixels (numba)
    tiles         tile culling and seeds for the refinement (numba)
    screen        world points to screen pixels
    raster        drawing virtual polygons over the reflector's pixels
    partpasses    a reflector's part passes drawn together over a label image
    compose       a frame's glue as kernels: mirrors in view and their screen boxes, part
                  stencils, corners gathered with flags, cracks closed over a box
"""
