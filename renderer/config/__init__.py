"""What a frame may ask for: the render settings, declared once, and the registry of methods."""
