"""``python -m droptower``: the same command as the ``droptower`` console script."""
import sys

from droptower.cli.main import main

sys.exit(main())
