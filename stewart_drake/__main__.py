"""``python -m stewart_drake``: the ``stewart-drake`` command (:func:`stewart_drake.cli.main.main`),
where no console script was installed or to choose the interpreter."""

import sys

from .cli.main import main

if __name__ == "__main__":
    sys.exit(main())
