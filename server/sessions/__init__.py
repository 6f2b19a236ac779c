"""The Model: sessions in their store, their scenes, the operations on them and the input caps they are
checked against, the gesture Controller, and the rate limit on creating them."""
