"""Campaign files: the long-format CSV (one row per touch) and its sidecar TOML.

reader.py reads and validates a CSV (every problem one line: file, row, column), sidecar.py reads
and writes NAME.toml beside NAME.csv, writer.py writes both atomically and deterministically,
summary.py says what a campaign holds (the `inspect --json` object), files.py checksums files and
reads and writes JSON documents (a diagnosis's study) atomically, merge.py appends new rings to a
campaign after checking that they belong to it.
"""

from ph_explorer.io.files import (
    campaign_files,
    campaign_sha256,
    checked_output_file,
    file_sha256,
    json_object_text,
    names_many,
    parse_json_object,
    read_json_object,
    write_json_object,
)
from ph_explorer.io.reader import KNOWN_COLUMNS, REQUIRED_COLUMNS, read_campaign
from ph_explorer.io.sidecar import sidecar_path
from ph_explorer.io.summary import campaign_summary
from ph_explorer.io.writer import write_campaign

__all__ = [
    "KNOWN_COLUMNS",
    "REQUIRED_COLUMNS",
    "campaign_files",
    "campaign_sha256",
    "checked_output_file",
    "campaign_summary",
    "file_sha256",
    "names_many",
    "json_object_text",
    "parse_json_object",
    "read_campaign",
    "read_json_object",
    "sidecar_path",
    "write_campaign",
    "write_json_object",
]
