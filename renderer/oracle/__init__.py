"""The independent oracles: the float64 NumPy tracer, our scene as a Mitsuba 3 scene, and the small
scenes compared with Mitsuba.
"""
