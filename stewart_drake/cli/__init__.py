"""The ``stewart-drake`` command: :mod:`.main` (``main(argv)``, the fault handling), a short
registry of subcommands (:mod:`.registry`), each living with its feature (``<feature>/command.py``),
and the parser's shared parts (:mod:`.core`). The options the features share live below them, in
:mod:`stewart_drake.execution` (``options``, ``trace_options``). The top of the package: nothing
else imports it. Imports nothing itself (see :mod:`.registry`)."""
