"""The real Sun as the reference: solar position (NREL SPA), the mount's frames, comparison of a sensor's
readings with the Sun (seed 003 §5) and the site and heading from the Sun's track (seed 001)."""
