"""Coarse sun sensors (seed 000): photodiodes and thermopiles on a cube's faces — their physics, the thesis'
numbers, bench calibration of each diode and attitude from a head's readings."""
