"""The commands: ``pocketray`` (cli) and the loopback scale-out stack."""
