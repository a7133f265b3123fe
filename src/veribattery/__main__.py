"""``python -m veribattery``: the command line, as the ``veribattery`` script runs it."""

from veribattery.cli import main

main()
