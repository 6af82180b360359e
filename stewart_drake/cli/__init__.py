"""The ``stewart-drake`` command: a short registry of subcommands, each living with its
feature. The top of the package: nothing imports it."""
