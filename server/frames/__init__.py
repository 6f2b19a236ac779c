"""Frames (the View): the pipeline every frame goes through (plan, admit, trace, encode), the GL worker that
traces them, their encoding (PNG, JPEG, NPY, EXR) and the device data."""
