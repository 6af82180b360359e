"""The ``stewart-drake`` command: :mod:`.main` (``main(argv)``, the fault handling), a short
registry of subcommands (:mod:`.registry`), each living with its feature (``<feature>/command.py``),
and the options they share (:mod:`.options`, ranked below the features, which import it). The top
of the package: nothing else imports it. Imports nothing itself (see :mod:`.registry`)."""
