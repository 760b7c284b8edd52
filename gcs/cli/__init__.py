"""The `fleetplan` command: one module per subcommand, dispatched from `gcs.cli.main`."""
