"""One module per ``akc-drake`` subcommand, each with ``main(args) -> int``."""
