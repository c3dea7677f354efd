"""Errors that reach a user as one clear line (file, row, column, what is wrong), never a traceback."""

from __future__ import annotations


class InputError(Exception):
    """Bad input from a file or an option. The CLI prints str(error) on one line and exits 2.

    column names a column of a file (a CSV column, a TOML key); option names a command-line
    option ("--add"), so that the line says "option --add", not "column --add".
    """

    def __init__(
        self,
        message: str,
        file: str | None = None,
        row: int | None = None,
        column: str | None = None,
        option: str | None = None,
    ):
        self.message = message
        self.file = file
        self.row = row
        self.column = column
        self.option = option
        super().__init__(self.line())

    def line(self) -> str:
        where = []
        if self.file is not None:
            where.append(str(self.file))
        if self.row is not None:
            where.append(f"row {self.row}")
        if self.column is not None:
            where.append(f"column {self.column}")
        if self.option is not None:
            where.append(f"option {self.option}")
        text = " ".join(self.message.split())  # one line, whatever the message held
        return f"{', '.join(where)}: {text}" if where else text
