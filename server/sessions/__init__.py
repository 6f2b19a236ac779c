"""The Model: sessions in their store, their scenes, the operations on them, the gesture Controller, and
the rate limit on creating them."""
