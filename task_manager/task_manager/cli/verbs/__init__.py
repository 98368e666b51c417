"""One module per taskctl verb."""
