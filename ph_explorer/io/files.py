"""Files as a whole: their checksum, and JSON documents written atomically and read with one clear line per problem."""

from __future__ import annotations

import glob
import hashlib
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.io.writer import atomic_write, csv_text


def file_sha256(path: Path) -> str:
    """The sha256 of a file's bytes, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def campaign_sha256(campaign: Campaign) -> str:
    """The sha256 of the CSV bytes `write_campaign` writes for this campaign: the identity of a
    campaign held in memory (a simulated scenario), equal to its file's once simulate --out wrote it."""
    return hashlib.sha256(csv_text(campaign).encode("utf-8")).hexdigest()


def read_json_object(path: Path, what: str) -> dict[str, Any]:
    """A JSON object from a file, or an InputError naming the file and what is wrong with it."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no such {what} file", file=str(path))
    return parse_json_object(path.read_bytes(), str(path), what)


def parse_json_object(content: bytes, source: str, what: str) -> dict[str, Any]:
    """A JSON object from a file's bytes (read, or uploaded by a browser), or an InputError naming
    the source and what is wrong with it."""
    try:
        document = json.loads(content.decode("utf-8"))
    except UnicodeDecodeError:
        raise InputError(f"not a {what}: not UTF-8 text", file=source) from None
    except json.JSONDecodeError as error:
        raise InputError(f"not a {what}: invalid JSON at line {error.lineno}, column {error.colno}", file=source) from None
    if not isinstance(document, dict):
        raise InputError(f"not a {what}: the file holds a JSON {type(document).__name__}, not an object", file=source)
    return document


def json_object_text(document: dict[str, Any]) -> str:
    """A JSON object as the project's files hold it (studies, cards): one key per line, a final newline."""
    return json.dumps(document, indent=1) + "\n"


def write_json_object(path: Path, document: dict[str, Any]) -> None:
    """Write a JSON object atomically: the old file stays whole until the new one is complete."""
    atomic_write([(Path(path), json_object_text(document))])


PATTERN = set("*?[")  # a --data value holding one of these is a glob pattern


def names_many(spec: str | Path) -> bool:
    """Whether a --data value names many campaigns: a glob pattern or a folder."""
    return bool(PATTERN & set(str(spec))) or Path(spec).is_dir()


def campaign_files(specs: Sequence[str | Path]) -> list[Path]:
    """The campaign CSVs that `specs` name (files, folders' *.csv, glob patterns), in the order
    given, each once; a pattern or folder that names no file is one line naming it."""
    found: list[Path] = []
    for spec in specs:
        text = str(spec)
        if PATTERN & set(text):
            matches = sorted(Path(p) for p in glob.glob(text) if Path(p).is_file())
            if not matches:
                raise InputError(f"{text}: no file matches the pattern", option="--data")
        elif Path(text).is_dir():
            matches = sorted(p for p in Path(text).glob("*.csv") if p.is_file())
            if not matches:
                raise InputError(f"{text}: the folder holds no .csv file", option="--data")
        else:
            matches = [Path(text)]
        found += [m for m in matches if m not in found]
    return found


def checked_output_file(path: Path, option: str, what: str, example: str) -> Path:
    """The file an option names to write, checked before any work: not a folder, in a folder that
    exists and is writable; else the one line that says which (what: "the report", example: "report.html")."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"is a folder: give {what}'s file name (e.g. {example})", file=str(path), option=option)
    if not path.parent.is_dir():
        raise InputError(f"no such folder for {what}", file=str(path.parent), option=option)
    if not os.access(path.parent, os.W_OK):
        raise InputError(f"{what}'s folder is not writable", file=str(path.parent), option=option)
    return path
