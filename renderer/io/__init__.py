"""Files in: model files (OBJ, PLY, STL, glTF/GLB) checked, unpacked and parsed into a model, and its
placing into a scene.
"""
