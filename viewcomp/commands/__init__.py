"""One module per `viewcomp` sub-command: each has ``register(subparsers)``."""
