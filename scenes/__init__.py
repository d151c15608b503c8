"""beo_bench.scenes (see DESIGN.md); filled in by its issue."""
