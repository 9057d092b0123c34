"""reflect: a batch renderer for mirror reflections."""

from . import openmp

# how numba's OpenMP workers wait between parallel loops (openmp.py): before any kernel runs
openmp.default_waiting()

__version__ = "0.1.0"
