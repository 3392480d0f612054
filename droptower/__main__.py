"""``python -m droptower``: the same command as the ``droptower`` console script."""
from droptower.cli.main import run

run()
