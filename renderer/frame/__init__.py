"""A frame planned: what a scene uses (the shader variant's features) and the one shader assembler, the
cost model, rasterised first hits, the plan and the preparation off the GL thread, the measured
profiles.
"""
