"""reflect: a batch renderer for mirror reflections."""

__version__ = "0.1.0"
