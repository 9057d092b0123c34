"""The Whitted ray tracer: Embree for triangles, numba for analytic mirrors and shading."""
