"""The routes, one module per resource: sessions, frames, meta, device, ws."""
