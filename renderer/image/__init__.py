"""A traced frame's pixels: its arrays, the tone map to png/jpeg, the denoisers."""
