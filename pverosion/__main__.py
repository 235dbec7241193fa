"""``python -m pverosion``: the same command line as the ``pverosion`` script."""

from pverosion.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
