"""One module per technique; `registry` maps names to them."""
