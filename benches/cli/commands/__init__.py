"""One module per ``tablebench`` subcommand; each defines ``register(subparsers)``."""
