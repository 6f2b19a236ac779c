"""Scenes made in code: the thesis's scenarios and the demo scenes, animated scenes and the Museum, and
how the trees follow motion.
"""
