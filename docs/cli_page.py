"""The command-line reference page, written from the typer app itself: `python docs/cli_page.py`.

Every command of `ph_explorer.cli.app` in the order `ph-explorer --help` lists them, with its help,
its usage line and each argument and option with its help, type and default. docs/hooks.py puts it
into the site as cli.md at build time; nothing here is copied by hand from the code.
"""

from __future__ import annotations

from typing import Any

# Where each command's method and output are described in the manual (a command missing here is
# still listed, without the link).
TOPIC_PAGES = {
    "inspect": ("Files and conventions", "formats.md#inspecting-a-campaign"),
    "merge": ("Files and conventions", "formats.md#merging-campaigns"),
    "simulate": ("The twin and its effects", "twin.md"),
    "train": ("Models", "models.md"),
    "evaluate": ("Models", "models.md#evaluate-the-papers-tables-1-3"),
    "diagnose": ("Diagnosis", "diagnosis.md"),
    "effects": ("The twin and its effects", "twin.md#what-a-campaign-can-see-of-each-effect"),
    "design": ("Designing a campaign", "planning.md"),
    "uncertainty": ("Uncertainty", "uncertainty.md"),
    "report": ("The explorer and reports", "explorer.md#reports"),
    "serve": ("The explorer and reports", "explorer.md"),
}

INTRO = """\
# Command line

This page is generated from the command line's own definitions (`ph_explorer.cli.app`) each time
the site is built, so it lists what `ph-explorer COMMAND --help` prints. `python -m ph_explorer`
runs the same program.

Exit status: 0 when the command did its work; 2 on bad input (a missing or malformed file, an
option out of range), with one line on stderr naming the file, the line and the column or the
option; 1 when an import fails (torch missing, say), with one line naming the command; 130 when
interrupted (Ctrl-C). Options that read a campaign also take the geometry
(`--pivot-to-ball-mm`, `--ball-diameter-mm`, `--bore-diameter-mm`), which win over the campaign's
sidecar TOML ([Files and conventions](formats.md#sidecar-toml)).
"""


def _cell(text: Any) -> str:
    """Text for one table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _type_name(param: Any, ctx: Any) -> str:
    """The parameter's type as --help shows it (typer's own click, or plain click)."""
    if getattr(param, "is_flag", False):
        return "flag"
    display = getattr(param, "display_type", None)
    if callable(display):
        return display(ctx).strip("<>")
    kind = getattr(param, "type", None)
    return getattr(kind, "name", "") or ""


def _default(param: Any) -> str:
    """The default as a reader needs it: a value, `off` for a flag, or - when there is none."""
    if getattr(param, "required", False):
        return "required"
    value = getattr(param, "default", None)
    if callable(value):
        value = None
    if getattr(param, "is_flag", False):
        return "off" if not value else "on"
    if value is None or value == ():
        return "-"
    return f"`{value}`"


def _names(param: Any) -> str:
    if getattr(param, "param_type_name", "") == "argument":
        return f"`{param.name.upper()}`"
    return ", ".join(f"`{name}`" for name in [*param.opts, *getattr(param, "secondary_opts", [])])


def command_section(name: str, command: Any, parent: Any) -> str:
    context = type(parent)(command, info_name=name, parent=parent)
    usage = " ".join(["ph-explorer", name, *command.collect_usage_pieces(context)])
    help_text = (command.help or "").strip()
    lines = [f"## {name}", "", help_text, "", "```text", usage, "```", ""]
    if name in TOPIC_PAGES:
        title, link = TOPIC_PAGES[name]
        lines += [f"Described in [{title}]({link}).", ""]
    params = [p for p in command.params if not getattr(p, "hidden", False)]
    if params:
        lines += ["| argument or option | type | default | what it is |", "|---|---|---|---|"]
        for param in params:
            help_cell = _cell(getattr(param, "help", "") or "")
            lines.append(f"| {_names(param)} | {_cell(_type_name(param, context))} | {_default(param)} | {help_cell} |")
        lines.append("")
    return "\n".join(lines)


CATALOG_MARKER = "<!-- effects-catalog -->"


def _parameter_text(parameter: Any, scan: dict[str, Any]) -> str:
    text = parameter.name
    if parameter.plausible is not None:
        low, high = parameter.plausible
        text += f" {low:g}-{high:g}"
    if parameter.name in scan:
        values = list(scan[parameter.name])
        text += f" scanned {min(values):g}-{max(values):g}"
    return text


def catalog_table() -> str:
    """Every effect of the default catalog: id, name, ISO 230-1 style symbol, axis, kind, parameters."""
    from ph_explorer.effects import DEFAULT_CATALOG

    lines = [
        "| id | name | symbol | axis | kind | parameters (plausible magnitude; scanned by the diagnosis) |",
        "|---|---|---|---|---|---|",
    ]
    for effect_id, effect in DEFAULT_CATALOG.items():
        parameters = ", ".join(_parameter_text(p, effect.scan or {}) for p in effect.parameters)
        symbol = getattr(effect, "symbol", "") or "-"
        lines.append(f"| `{effect_id}` | {_cell(effect.name)} | {symbol} | {effect.axis or '-'} | {effect.kind} | {_cell(parameters)} |")
    return "\n".join(lines) + "\n"


def render() -> str:
    """The whole page, as markdown."""
    import typer

    from ph_explorer.cli import app

    group = typer.main.get_command(app)
    root = group.context_class(group, info_name="ph-explorer")
    names = group.list_commands(root)
    lines = [INTRO, f"{group.help.strip()}", "", "| command | what it does |", "|---|---|"]
    for name in names:
        command = group.get_command(root, name)
        summary = _cell(command.get_short_help_str(limit=300))
        lines.append(f"| [`{name}`](#{name}) | {summary} |")
    lines.append("")
    for name in names:
        lines.append(command_section(name, group.get_command(root, name), root))
    return "\n".join(lines)


if __name__ == "__main__":
    print(render())
