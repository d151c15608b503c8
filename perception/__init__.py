"""beo_bench.perception (see DESIGN.md); filled in by its issue."""
