"""Sub-commands of ``vega``: one module per sub-command, each exporting ``register(subparsers)``."""
