"""``python -m are_stats``: the ``are-stats`` command line."""

from are_stats.cli import main

main()
