"""beo_bench.envs (see DESIGN.md); filled in by its issue."""
