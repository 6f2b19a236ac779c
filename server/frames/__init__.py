"""Frames (the View): the GL worker that traces them, their encoding (PNG, JPEG, NPY, EXR) and the device data."""
