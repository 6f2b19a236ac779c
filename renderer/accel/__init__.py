"""Acceleration methods, GL-free (NumPy only): one module per method, its GPU layout and
packer beside it (``<method>_layout.py``), the interface in ``base``. The registry that
names them is :mod:`renderer.config.methods`; the implementations never import it."""
