"""A command line that cannot be parsed (an unknown option, a value of the wrong type, a missing
one) is one line naming the command, exit 2, as every bad input of ph-explorer is; typer would
draw it as a panel of several lines."""

from __future__ import annotations

import typer

try:  # typer 0.2x carries its own click; older typers raise click's exceptions
    from typer._click import exceptions as click_errors
except ImportError:  # pragma: no cover
    from click import exceptions as click_errors  # type: ignore[no-redef]


def run_console(app: typer.Typer) -> None:
    """Run the app as the console script does, with one line for what cannot be parsed; exits."""
    try:
        code = app(prog_name="ph-explorer", standalone_mode=False)
    except click_errors.UsageError as error:
        if isinstance(error, getattr(click_errors, "NoArgsIsHelpError", ())):  # the command alone: its help, as typer shows it
            error.show()
            raise SystemExit(2) from None
        where = error.ctx.command_path if error.ctx is not None else "ph-explorer"
        message = " ".join(error.format_message().split())
        names = getattr(getattr(error, "param", None), "opts", None)
        if type(error) is click_errors.BadParameter and names:  # a value of the wrong type: worded as every bad option is
            message = f"option {max(names, key=len)}: {' '.join(error.message.split()).rstrip('.')}"
        else:
            message = f"{where}: {message}"
        typer.echo(f"{message} ({where} --help lists the options)", err=True)
        raise SystemExit(2) from None
    except click_errors.ClickException as error:
        typer.echo(f"ph-explorer: {' '.join(error.format_message().split())}", err=True)
        raise SystemExit(error.exit_code) from None
    except typer.Abort:
        typer.echo("ph-explorer: interrupted", err=True)
        raise SystemExit(130) from None
    raise SystemExit(code if isinstance(code, int) else 0)
