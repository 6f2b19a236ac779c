"""What the GPU reads, GL-free: every binding, the shader variants' reads, the record layouts and the
packers.
"""
