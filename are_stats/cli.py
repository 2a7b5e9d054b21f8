"""The ``are-stats`` command line: thin wrappers over the package's functions."""

from __future__ import annotations

import typer

from are_stats import __version__

app = typer.Typer(
    name="are-stats",
    help=(
        "ARE toolkit: fit artefact life-cycle priors from field logs, generate "
        "posterior-predictive scenarios, build augmented maps, compute what the robot "
        "perceives and run navigation experiments."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.command()
def version() -> None:
    """Print the are_stats version."""
    typer.echo(__version__)


def main() -> None:  # pragma: no cover - console entry
    app()
