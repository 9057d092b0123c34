"""Writing frames (EXR, PNG previews) atomically, and timing logs."""
