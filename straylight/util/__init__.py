"""Small utilities with no physics: grid interpolation for the hot loops, safe product writing and
the per-job worker pool."""
