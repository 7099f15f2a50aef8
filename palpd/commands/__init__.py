"""One module per palpd subcommand: argument handling and output, no domain logic."""
