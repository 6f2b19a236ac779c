"""pocketray's render service: sessions (Model), gestures (Controller), frames (View).

Run with ``python -m server`` (``./dev serve``); the ASGI app is ``server.app:app``.
"""
