"""The scene and its geometry: the scene model (spheres, planes, meshes, analytic shapes, lights,
camera), the shapes' float64 tests, the procedural meshes and the teapot's data.
"""
