"""The parts of bench/run.py, by what they measure: the shared samples, models and charts
(common), the Earth's grids and tables (earthshine), the PST grid (pst), the stars' split and
skip (stars), sampling in time and on the sky (sampling), the cube's speed and the plan's and
auto's cost figures (cube), and the speed and accuracy goal's figures (goal)."""
