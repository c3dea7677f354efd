"""The `ph-explorer` command line: inspect, simulate, train, evaluate, diagnose, effects, design, uncertainty, report, serve, merge.

This module holds the typer app, the options each command takes and one wrapper; the work of each
command is in its own module (cli/inspect_command.py, ...). A command module imports the torch- or
viser-bound core only when the command runs, so that `ph-explorer inspect` works without torch.

What a user sees when something goes wrong (the wrapper, `_run`): bad input (InputError) is one
line on stderr and exit 2; an import that fails (e.g. torch missing) is one line naming the command
and the error, exit 1; Ctrl-C is exit 130.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from inspect import Parameter, signature as function_signature
from pathlib import Path
from typing import Annotated, Any, Optional

import typer

from ph_explorer.cli import (
    design_command as design,
    diagnose_command as diagnose,
    effects_command as effects,
    evaluate_command as evaluate,
    fleet_command as fleet,
    inspect_command as inspect,
    merge_command as merge,
    report_command as report,
    serve_command as serve,
    simulate_command as simulate,
    train_command as train,
    uncertainty_command as uncertainty,
)
from ph_explorer.cli.usage_errors import run_console
from ph_explorer.errors import InputError
from ph_explorer.io import names_many

app = typer.Typer(
    name="ph-explorer",
    help="Explore, model and diagnose the orientation-dependent errors of a PH20/TP20 five-axis probe head.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

ScenarioOpt = Annotated[Optional[str], typer.Option(help="A shipped scenario name or a scenario TOML path.")]
# Options shared by every command that reads a campaign CSV.
PivotOpt = Annotated[
    Optional[float], typer.Option("--pivot-to-ball-mm", help="Pivot-to-ball-centre distance L (default 80, or the sidecar TOML).")
]
BallOpt = Annotated[Optional[float], typer.Option("--ball-diameter-mm", help="Stylus ball diameter (default 2).")]
BoreOpt = Annotated[Optional[float], typer.Option("--bore-diameter-mm", help="Ring bore diameter (default 20).")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]


GEOMETRY_OPTIONS = {"pivot_to_ball_mm": PivotOpt, "ball_diameter_mm": BallOpt, "bore_diameter_mm": BoreOpt}


def with_geometry(command: Callable[..., None]) -> Callable[..., None]:
    """Give a command the geometry options of every command that reads a campaign.

    The command declares one parameter `geometry`; typer sees the three options in its place, and
    the command receives the ones given as a dict keyed as the sidecar's [geometry] keys.
    """
    signature = function_signature(command, eval_str=True)
    options = [
        Parameter(name, Parameter.KEYWORD_ONLY, default=None, annotation=annotation) for name, annotation in GEOMETRY_OPTIONS.items()
    ]
    parameters = [p for p in signature.parameters.values() if p.name != "geometry"] + options

    @functools.wraps(command)
    def wrapper(**given: Any) -> None:
        values = {name: given.pop(name) for name in GEOMETRY_OPTIONS}
        command(geometry={k: v for k, v in values.items() if v is not None}, **given)

    wrapper.__signature__ = signature.replace(parameters=parameters)  # type: ignore[attr-defined]
    wrapper.__annotations__ = {p.name: p.annotation for p in parameters}
    return wrapper


def _run(command: str, work: Callable[..., int | None], **options: Any) -> None:
    """Run one command's work and turn its outcome into an exit status (see the module docstring)."""
    try:
        code = work(**options)
    except InputError as error:
        typer.echo(error.line(), err=True)
        raise typer.Exit(2) from None
    except ImportError as error:
        message = " ".join(str(error).split())  # one line, whatever the import machinery said
        typer.echo(f"ph-explorer {command}: {type(error).__name__}: {message}", err=True)
        raise typer.Exit(1) from None
    except KeyboardInterrupt:
        typer.echo("ph-explorer: interrupted", err=True)
        raise typer.Exit(130) from None
    raise typer.Exit(int(code or 0))


@app.command("serve")
@with_geometry
def _serve(
    scenario: ScenarioOpt = None,
    data: Annotated[Optional[Path], typer.Option(help="A campaign CSV to explore.")] = None,
    model: Annotated[Optional[Path], typer.Option(help="A trained model folder (default: assets/models/paper).")] = None,
    host: Annotated[str, typer.Option(help="Address to bind; 127.0.0.1 keeps it on this machine.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="Port to bind (0 picks a free one).")] = 8080,
    study: Annotated[
        Optional[Path],
        typer.Option(
            help="A study of the served campaign to open and continue (diagnose --save makes one; created on the first Save study if absent)."
        ),
    ] = None,
    effects: Annotated[
        Optional[Path],
        typer.Option(help="A Python file defining your own effects, read by the server at start (a browser never uploads code)."),
    ] = None,
    geometry: dict[str, float] | None = None,
) -> None:
    """Start the 3D explorer in the browser (default: the shipped paper campaign and assets/models/paper)."""
    _run(
        "serve",
        serve.serve_command,
        scenario=scenario,
        data=data,
        model=model,
        host=host,
        port=port,
        study=study,
        effects=effects,
        geometry=geometry,
    )


@app.command("simulate")
def _simulate(
    scenario: ScenarioOpt = None,
    out: Annotated[Optional[Path], typer.Option(help="The campaign CSV to write (a sidecar TOML is written beside it).")] = None,
    seed: Annotated[Optional[int], typer.Option(help="Random seed (default: the scenario's).")] = None,
    list_scenarios: Annotated[bool, typer.Option("--list", help="List the shipped scenarios and exit.")] = False,
    random_head: Annotated[
        Optional[str], typer.Option(help="Instead of a scenario: a random healthy head drawn from this integer seed.")
    ] = None,
    design: Annotated[
        Optional[str], typer.Option(help="The random head's design: paper, coarse, no_times or other_geometry (default: drawn).")
    ] = None,
    hidden_effect: Annotated[Optional[str], typer.Option(help="Add one hidden catalog effect (an id) to the random head.")] = None,
    strength: Annotated[
        Optional[str], typer.Option(help="The hidden effect's size in multiples of its detection limit (default: drawn from 1-3).")
    ] = None,
    rings: Annotated[
        Optional[Path],
        typer.Option(
            help="With --scenario: its head measured at these rings only, after its campaign (of --seed), on another noise draw; a CSV with A_deg, B_deg, as design --decide --out writes."
        ),
    ] = None,
    adaptive: Annotated[
        bool, typer.Option("--adaptive", help="Measure the head plan by plan until the stop (design --start, --next).")
    ] = False,
    budget_minutes: Annotated[Optional[float], typer.Option(help="With --adaptive: the minutes at the machine it may take.")] = None,
) -> None:
    """Simulate a campaign with the digital twin of the head, or a random head of the population."""
    _run(
        "simulate",
        simulate.simulate_command,
        scenario=scenario,
        out=out,
        seed=seed,
        list_scenarios=list_scenarios,
        random_head=random_head,
        design=design,
        hidden_effect=hidden_effect,
        strength=strength,
        rings=rings,
        adaptive=adaptive,
        budget_minutes=budget_minutes,
    )


@app.command("train")
@with_geometry
def _train(
    data: Annotated[Path, typer.Option(help="The campaign CSV to train on.")],
    out: Annotated[Path, typer.Option(help="The model folder to write (written atomically).")],
    holdout: Annotated[
        Optional[str], typer.Option(help="Held-out orientations 'A:B,A:B' (default: the sidecar's check rings, else the off-grid ones).")
    ] = None,
    seed: Annotated[int, typer.Option(help="Random seed of the network's training.")] = 0,
    max_epochs: Annotated[
        Optional[int],
        typer.Option(min=1, help="Stop the network's training after this many epochs (default: the paper's early stopping, at most 2000)."),
    ] = None,
    data_part: Annotated[
        Optional[str],
        typer.Option(help="Also fit this data-driven part beside them, for the explorer and evaluate: gp (a Gaussian process, gp.npz)."),
    ] = None,
    geometry: dict[str, float] | None = None,
) -> None:
    """Train the paper's network and the trilinear + Monte Carlo model on a campaign."""
    _run(
        "train",
        train.train_command,
        data=data,
        out=out,
        holdout=holdout,
        seed=seed,
        geometry=geometry,
        max_epochs=max_epochs,
        data_part=data_part,
    )


@app.command("evaluate")
@with_geometry
def _evaluate(
    model: Annotated[Path, typer.Option(help="A trained model folder.")],
    data: Annotated[Path, typer.Option(help="The campaign CSV with the measurements to compare with.")],
    json_output: JsonOpt = False,
    strict: Annotated[
        bool, typer.Option("--strict", help="A model trained on another file than --data is an error (exit 2), not a warning.")
    ] = False,
    geometry: dict[str, float] | None = None,
) -> None:
    """The paper's Tables 1-3 at every held-out orientation."""
    _run("evaluate", evaluate.evaluate_command, model=model, data=data, json_output=json_output, geometry=geometry, strict=strict)


@app.command("diagnose")
@with_geometry
def _diagnose(
    data: Annotated[
        list[Path],
        typer.Option(
            help="The campaign CSV to diagnose; several (repeat --data), a folder or a quoted glob ('heads/*.csv') diagnose a fleet."
        ),
    ],
    model: Annotated[Optional[Path], typer.Option(help="A trained model folder to start from.")] = None,
    add: Annotated[Optional[str], typer.Option(help="Effects to add, 'ID[,ID]' (default: the best candidate, if any).")] = None,
    effects: Annotated[
        Optional[Path], typer.Option(help="A Python file defining your own effects, or a shapes file (.toml) from --export-shapes.")
    ] = None,
    data_part: Annotated[
        Optional[str],
        typer.Option(
            help=(
                "Data-driven part of the hybrid: trilinear (refits in seconds), network (retrained) or gp (a Gaussian process,"
                " scikit-learn's). Default: trilinear, or the study's."
            )
        ),
    ] = None,
    save: Annotated[
        Optional[Path], typer.Option(help="Write the study (every step, its effects and errors, the verdict) to this JSON file.")
    ] = None,
    resume: Annotated[
        Optional[Path],
        typer.Option(
            help="Continue a study of this campaign from the model it reached; saved back to it unless --save names another file."
        ),
    ] = None,
    json_output: JsonOpt = False,
    detail: Annotated[
        str,
        typer.Option(
            help="How much the text report says: short (the verdict, claims, worst rings, history) or full (every candidate and test)."
        ),
    ] = "short",
    scheduler: Annotated[
        Optional[str],
        typer.Option(help="A fleet on this Dask scheduler (tcp://HOST:PORT) instead of a local cluster of this machine's cores."),
    ] = None,
    report: Annotated[
        Optional[Path],
        typer.Option(help="A fleet's page: this HTML file with the fleet's table, each campaign's own report written beside it."),
    ] = None,
    export_shapes: Annotated[
        Optional[Path],
        typer.Option(
            "--export-shapes",
            help="Write the shapes found (what no catalog holds) to this TOML file: read it back with --effects, add one with --add ID.",
        ),
    ] = None,
    geometry: dict[str, float] | None = None,
) -> None:
    """Find where a model fails, which physical effect is missing, add it and show the error fall."""
    options = {"model": model, "add": add, "effects": effects, "data_part": data_part, "json_output": json_output}
    if len(data) > 1 or scheduler is not None or report is not None or names_many(data[0]):
        single = {"--save": save, "--resume": resume, "--export-shapes": export_shapes}
        for name in (name for name, value in single.items() if value is not None):
            typer.echo(
                f"option {name}: {'a shapes file' if 'shapes' in name else 'a study'} is of one campaign; diagnose it alone", err=True
            )
            raise typer.Exit(2)
        _run("diagnose", fleet.fleet_command, specs=data, scheduler=scheduler, report=report, geometry=geometry, **options)
    one = {"save": save, "resume": resume, "detail": detail, "export_shapes": export_shapes}
    _run("diagnose", diagnose.diagnose_command, data=data[0], geometry=geometry, **one, **options)


@app.command("effects")
@with_geometry
def _effects(
    data: Annotated[Optional[Path], typer.Option(help="A campaign CSV: what its design lets head touches see of each effect.")] = None,
    effects_file: Annotated[Optional[Path], typer.Option("--effects", help="A Python file defining your own effects.")] = None,
    json_output: JsonOpt = False,
    geometry: dict[str, float] | None = None,
) -> None:
    """Every effect of the catalog (id, ISO 230-1 style symbol, axis, kind, parameters); with --data, which
    the campaign can see, which the circle fit absorbs, which the data model learns, which are confounded."""
    _run("effects", effects.effects_command, data=data, effects=effects_file, json_output=json_output, geometry=geometry)


@app.command("design")
@with_geometry
def _design(
    budget: Annotated[Optional[int], typer.Option(help="How many rings to propose (with --decide: at most; default 6).")] = None,
    data: Annotated[Optional[Path], typer.Option(help="A campaign CSV already measured: the next rings.")] = None,
    decide: Annotated[bool, typer.Option("--decide", help="With --data: the rings that decide what its diagnosis cannot.")] = False,
    out: Annotated[Optional[Path], typer.Option(help="With --decide, --start or --next: the rings as a CSV.")] = None,
    study: Annotated[Optional[Path], typer.Option(help="With --decide: continue this study, as diagnose --resume does.")] = None,
    start: Annotated[bool, typer.Option("--start", help="The first rings of an adaptive campaign (no data).")] = False,
    next_rings: Annotated[bool, typer.Option("--next", help="With --data: the next rings of an adaptive campaign, or the stop.")] = False,
    budget_minutes: Annotated[Optional[float], typer.Option(help="With --start, --next: the campaign's time at the machine.")] = None,
    tolerance_um: Annotated[Optional[float], typer.Option(help="With --start, --next: what the model may miss at unseen rings.")] = None,
    sigma_um: Annotated[Optional[float], typer.Option(help="With --start: the probe's repeatability, um (default 0.175).")] = None,
    after: Annotated[Optional[Path], typer.Option(help="With --next: the last plan's JSON, its questions not asked again.")] = None,
    effects_file: Annotated[Optional[Path], typer.Option("--effects", help="A Python file defining your own effects.")] = None,
    json_output: JsonOpt = False,
    geometry: dict[str, float] | None = None,
) -> None:
    """Which rings to measure and in what order: the catalog's effects identifiable (D-optimal on their
    bases at the head touches) and the data part covered (space filling); with --data, the next rings;
    with --decide, the rings that decide between the diagnosis's candidates; with --start, then --next,
    an adaptive campaign that measures until the answer is known."""
    options = {"data": data, "decide": decide, "out": out, "study": study, "effects": effects_file, "json_output": json_output}
    options |= {"start": start, "next_rings": next_rings, "budget_minutes": budget_minutes, "tolerance_um": tolerance_um}
    options |= {"sigma_um": sigma_um, "after": after}
    _run("design", design.design_command, budget=budget, geometry=geometry, **options)


@app.command("uncertainty")
def _uncertainty(
    model: Annotated[Path, typer.Option(help="A trained model folder (with its uncertainty.npz).")],
    orientations: Annotated[str, typer.Option(help="Orientations 'A:B[,A:B...]' in degrees, e.g. 15:-20,43:90.")],
    level: Annotated[float, typer.Option(help="Coverage probability of the bands, in (0, 1).")] = 0.95,
    seed: Annotated[Optional[int], typer.Option(help="Random seed of the Monte Carlo (default: fresh).")] = None,
    digits: Annotated[
        int, typer.Option(help="Significant digits the Monte Carlo's results must be stable to (JCGM 101 7.9): 1 is a quick look.")
    ] = 2,
    json_output: JsonOpt = False,
) -> None:
    """Each model's Monte Carlo band with every component (repeatability, model, parameters), its budget
    and the RONt of one measurement with U (k = 2), at the given orientations."""
    _run(
        "uncertainty",
        uncertainty.uncertainty_command,
        model=model,
        orientations=orientations,
        level=level,
        json_output=json_output,
        seed=seed,
        digits=digits,
    )


@app.command("report")
@with_geometry
def _report(
    out: Annotated[Path, typer.Option(help="The HTML file to write (one file, its figures inside; written atomically).")],
    data: Annotated[Optional[Path], typer.Option(help="The campaign CSV to report on.")] = None,
    scenario: ScenarioOpt = None,  # simulated with its own seed, instead of --data
    model: Annotated[
        Optional[Path], typer.Option(help="A trained model folder: its models are shown and the diagnosis starts from it.")
    ] = None,
    study: Annotated[
        Optional[Path], typer.Option(help="A study of this campaign (diagnose --save, the explorer's Save study); default: diagnose now.")
    ] = None,
    orientations: Annotated[
        Optional[str],
        typer.Option(help="Where to draw polar plots and Tables 1-3, 'A:B[,A:B...]' (default: the worst failing ring and a check ring)."),
    ] = None,
    reveal: Annotated[
        bool, typer.Option("--reveal", help="Name a teaching scenario's hidden effects, with their true parameters.")
    ] = False,
    geometry: dict[str, float] | None = None,
) -> None:
    """A campaign and its diagnosis as one HTML file: the campaign, the error map, polar plots and
    Tables 1-3, the verdict, the fitted effects +- U, the error history and where it fails."""
    options = {"data": data, "scenario": scenario, "model": model, "study": study, "orientations": orientations, "reveal": reveal}
    _run("report", report.report_command, out=out, geometry=geometry, **options)


@app.command("inspect")
@with_geometry
def _inspect(
    file: Annotated[Path, typer.Argument(help="A campaign CSV.")],
    json_output: JsonOpt = False,
    geometry: dict[str, float] | None = None,
) -> None:
    """What a campaign holds: orientations, lattice, off-grid rings, noise."""
    _run("inspect", inspect.inspect_command, file=file, json_output=json_output, geometry=geometry)


@app.command("merge")
@with_geometry
def _merge(
    base: Annotated[Path, typer.Argument(help="The campaign CSV measured first.")],
    new: Annotated[Path, typer.Argument(help="The campaign CSV of the new rings, measured after it on the same set-up.")],
    out: Annotated[Path, typer.Option(help="The merged campaign CSV to write (its sidecar TOML beside it); never an input.")],
    replace: Annotated[bool, typer.Option("--replace", help="Let a new ring stand in place of the same orientation in BASE.")] = False,
    json_output: JsonOpt = False,
    geometry: dict[str, float] | None = None,
) -> None:
    """Append new rings to a campaign: the same set-up, repetitions and kind of file, times after the base's."""
    _run("merge", merge.merge_command, base=base, new=new, out=out, replace=replace, json_output=json_output, geometry=geometry)


def main() -> None:
    """The console script `ph-explorer` (a command line that cannot be parsed: cli/usage_errors.py)."""
    run_console(app)
