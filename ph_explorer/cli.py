"""The `ph-explorer` command line: serve, simulate, train, evaluate, diagnose, inspect.

Each subcommand only parses options and calls one function of the core (or of the app for
serve). Bad input raises InputError, printed here as one line on stderr with exit status 2.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from typing import Annotated, Any, Optional

import typer

app = typer.Typer(
    name="ph-explorer",
    help="Explore, model and diagnose the orientation-dependent errors of a PH20/TP20 five-axis probe head.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

# Options shared by every command that reads a campaign CSV.
PivotOpt = Annotated[
    Optional[float], typer.Option("--pivot-to-ball-mm", help="Pivot-to-ball-centre distance L (default 80, or the sidecar TOML).")
]
BallOpt = Annotated[Optional[float], typer.Option("--ball-diameter-mm", help="Stylus ball diameter (default 2).")]
BoreOpt = Annotated[Optional[float], typer.Option("--bore-diameter-mm", help="Ring bore diameter (default 20).")]


def _geometry_overrides(pivot: float | None, ball: float | None, bore: float | None) -> dict[str, float]:
    given = {"pivot_to_ball_mm": pivot, "ball_diameter_mm": ball, "bore_diameter_mm": bore}
    return {k: v for k, v in given.items() if v is not None}


def _run(target: str, issue: int, **kwargs: Any) -> None:
    """Call `module:function` with kwargs; turn InputError into one line and exit 2."""
    from ph_explorer.errors import InputError

    module_name, func_name = target.split(":")
    try:
        func = getattr(importlib.import_module(module_name), func_name)
    except (ImportError, AttributeError):
        typer.echo(f"ph-explorer: this command is not implemented yet (see issue {issue})", err=True)
        raise typer.Exit(1)
    try:
        code = func(**kwargs)
    except InputError as error:
        typer.echo(error.line(), err=True)
        raise typer.Exit(2)
    except KeyboardInterrupt:
        typer.echo("ph-explorer: interrupted", err=True)
        raise typer.Exit(130)
    raise typer.Exit(int(code or 0))


@app.command()
def serve(
    scenario: Annotated[Optional[str], typer.Option(help="A shipped scenario name or a scenario TOML path.")] = None,
    data: Annotated[Optional[Path], typer.Option(help="A campaign CSV to explore.")] = None,
    model: Annotated[Optional[Path], typer.Option(help="A trained model folder (default: model/paper).")] = None,
    host: Annotated[str, typer.Option(help="Address to bind; 127.0.0.1 keeps it on this machine.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="Port to bind (0 picks a free one).")] = 8080,
    pivot_to_ball_mm: PivotOpt = None,
    ball_diameter_mm: BallOpt = None,
    bore_diameter_mm: BoreOpt = None,
) -> None:
    """Start the 3D explorer in the browser (default: the shipped paper campaign and model/paper)."""
    _run(
        "ph_explorer.app.server:serve_command",
        6,
        scenario=scenario,
        data=data,
        model=model,
        host=host,
        port=port,
        geometry=_geometry_overrides(pivot_to_ball_mm, ball_diameter_mm, bore_diameter_mm),
    )


@app.command()
def simulate(
    scenario: Annotated[Optional[str], typer.Option(help="A shipped scenario name or a scenario TOML path.")] = None,
    out: Annotated[Optional[Path], typer.Option(help="The campaign CSV to write (a sidecar TOML is written beside it).")] = None,
    seed: Annotated[Optional[int], typer.Option(help="Random seed (default: the scenario's).")] = None,
    list_scenarios: Annotated[bool, typer.Option("--list", help="List the shipped scenarios and exit.")] = False,
) -> None:
    """Simulate a campaign with the digital twin of the head."""
    _run("ph_explorer.twin:simulate_command", 3, scenario=scenario, out=out, seed=seed, list_scenarios=list_scenarios)


@app.command()
def train(
    data: Annotated[Path, typer.Option(help="The campaign CSV to train on.")],
    out: Annotated[Path, typer.Option(help="The model folder to write (written atomically).")],
    holdout: Annotated[
        Optional[str], typer.Option(help="Held-out orientations 'A:B,A:B' (default: the sidecar's check rings, else the off-grid ones).")
    ] = None,
    seed: Annotated[int, typer.Option(help="Random seed of the network's training.")] = 0,
    pivot_to_ball_mm: PivotOpt = None,
    ball_diameter_mm: BallOpt = None,
    bore_diameter_mm: BoreOpt = None,
) -> None:
    """Train the paper's network and the trilinear + Monte Carlo model on a campaign."""
    _run(
        "ph_explorer.training:train_command",
        4,
        data=data,
        out=out,
        holdout=holdout,
        seed=seed,
        geometry=_geometry_overrides(pivot_to_ball_mm, ball_diameter_mm, bore_diameter_mm),
    )


@app.command()
def evaluate(
    model: Annotated[Path, typer.Option(help="A trained model folder.")],
    data: Annotated[Path, typer.Option(help="The campaign CSV with the measurements to compare with.")],
    json_output: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    pivot_to_ball_mm: PivotOpt = None,
    ball_diameter_mm: BallOpt = None,
    bore_diameter_mm: BoreOpt = None,
) -> None:
    """The paper's Tables 1-3 at every held-out orientation."""
    _run(
        "ph_explorer.evaluation:evaluate_command",
        4,
        model=model,
        data=data,
        json_output=json_output,
        geometry=_geometry_overrides(pivot_to_ball_mm, ball_diameter_mm, bore_diameter_mm),
    )


@app.command()
def diagnose(
    data: Annotated[Path, typer.Option(help="The campaign CSV to diagnose.")],
    model: Annotated[Optional[Path], typer.Option(help="A trained model folder to start from.")] = None,
    add: Annotated[Optional[str], typer.Option(help="Effects to add, 'ID[,ID]' (default: the best candidate, if any).")] = None,
    effects: Annotated[Optional[Path], typer.Option(help="A Python file defining your own effects.")] = None,
    data_part: Annotated[
        str, typer.Option(help="Data-driven part of the hybrid: trilinear (refits in seconds) or network (retrained).")
    ] = "trilinear",
    json_output: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    pivot_to_ball_mm: PivotOpt = None,
    ball_diameter_mm: BallOpt = None,
    bore_diameter_mm: BoreOpt = None,
) -> None:
    """Find where a model fails, which physical effect is missing, add it and show the error fall."""
    _run(
        "ph_explorer.diagnosis:diagnose_command",
        5,
        data=data,
        model=model,
        add=add,
        effects=effects,
        data_part=data_part,
        json_output=json_output,
        geometry=_geometry_overrides(pivot_to_ball_mm, ball_diameter_mm, bore_diameter_mm),
    )


@app.command()
def inspect(
    file: Annotated[Path, typer.Argument(help="A campaign CSV.")],
    json_output: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    pivot_to_ball_mm: PivotOpt = None,
    ball_diameter_mm: BallOpt = None,
    bore_diameter_mm: BoreOpt = None,
) -> None:
    """What a campaign holds: orientations, lattice, off-grid rings, noise."""
    _run(
        "ph_explorer.io:inspect_command",
        2,
        file=file,
        json_output=json_output,
        geometry=_geometry_overrides(pivot_to_ball_mm, ball_diameter_mm, bore_diameter_mm),
    )


def main() -> None:
    app(prog_name="ph-explorer")


if __name__ == "__main__":
    sys.exit(main())
