"""Property: whatever bytes a campaign file holds, read_campaign returns a Campaign or raises
InputError, never another exception."""

from __future__ import annotations

from pathlib import Path
from unittest.mock import patch

import numpy as np
from hypothesis import HealthCheck, example, given, settings, strategies as st

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.io import read_campaign

VALID_LINES = ["A_deg,B_deg,rep,point,dev_um,t_s"] + [
    f"{a},{b},{r},{k},{0.01 * (k - 2):.2f},{((o * 2 + r) * 4 + k) * 0.5}"
    for o, (a, b) in enumerate([(0, 0), (30, 20)])
    for r in range(2)
    for k in range(4)
]
VALID = ("\n".join(VALID_LINES) + "\n").encode()

# Text that looks like a campaign: field separators, numbers, signs, the column names, junk.
TOKENS = st.sampled_from(
    [
        ",",
        "\n",
        "\r\n",
        '"',
        " ",
        "0",
        "1",
        "-1",
        "3",
        "15",
        "1e9",
        "-0.5",
        "nan",
        "inf",
        "-inf",
        "1e400",
        "A_deg",
        "B_deg",
        "rep",
        "point",
        "dev_um",
        "t_s",
        "x_mm",
        "y_mm",
        "abc",
        "\x00",
        "\ufeff",
        "é",
        ";",
        "\t",
        "200",
    ]
)
csvish = st.lists(TOKENS, max_size=80).map(lambda parts: "".join(parts).encode("utf-8"))


@st.composite
def mutated(draw: st.DrawFn) -> bytes:
    """The valid file with a few bytes replaced, inserted or deleted, or lines dropped or repeated."""
    data = bytearray(VALID)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["replace", "insert", "delete", "drop_line", "repeat_line"]))
        if not data:
            break
        i = draw(st.integers(0, len(data) - 1))
        if kind == "replace":
            data[i] = draw(st.integers(0, 255))
        elif kind == "insert":
            data[i:i] = draw(st.binary(min_size=1, max_size=6))
        elif kind == "delete":
            del data[i : i + draw(st.integers(1, 6))]
        else:
            lines = bytes(data).split(b"\n")
            j = draw(st.integers(0, len(lines) - 1))
            if kind == "drop_line":
                del lines[j]
            else:
                lines.insert(j, lines[j])
            data = bytearray(b"\n".join(lines))
    return bytes(data)


def _load(tmp_path: Path, data: bytes) -> Campaign | None:
    path = tmp_path / "campaign.csv"
    path.write_bytes(data)
    try:
        campaign = read_campaign(path)
    except InputError as error:
        line = error.line()
        assert "\n" not in line and str(path) in line
        return None
    assert np.isfinite(campaign.deviations).all()
    return campaign


SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def test_the_valid_file_loads(tmp_path: Path) -> None:
    c = _load(tmp_path, VALID)
    assert c is not None and c.deviations.shape == (2, 2, 4)


@given(data=st.binary(max_size=300))
@example(data=b"")
@example(data=b"\xff\xfe\x00A")
@SETTINGS
def test_random_bytes(tmp_path: Path, data: bytes) -> None:
    _load(tmp_path, data)


@given(data=csvish)
@example(data=b'",\n,"')  # a quoted header cell holding a newline: the error must stay one line
@SETTINGS
def test_csv_like_text(tmp_path: Path, data: bytes) -> None:
    _load(tmp_path, data)


@given(data=mutated())
@example(data=VALID.replace(b"0,0,0,0", b"0,0,0,0,1"))
@example(data=VALID.replace(b"t_s\n", b"t_s,x_mm\n"))
@example(data=VALID + b"0,0,0,5000000000,1,1\n")
@SETTINGS
def test_mutated_campaigns(tmp_path: Path, data: bytes) -> None:
    _load(tmp_path, data)


@given(
    cell=st.sampled_from(["", "x", "nan", "inf", "1,5", '"', "1e999", "0x1"]),
    row=st.integers(1, len(VALID_LINES) - 1),
    column=st.integers(0, 5),
)
@SETTINGS
def test_a_bad_cell_is_always_an_input_error_at_its_row(tmp_path: Path, cell: str, row: int, column: int) -> None:
    """A bad value in any cell is reported at its own line (1-based, header = 1)."""
    lines = list(VALID_LINES)
    fields = lines[row].split(",")
    fields[column] = cell
    lines[row] = ",".join(fields)
    path = tmp_path / "campaign.csv"
    path.write_text("\n".join(lines) + "\n")
    try:
        read_campaign(path)
    except InputError as error:
        assert error.row == row + 1, error.line()
    else:
        raise AssertionError(f"accepted a bad cell {cell!r}")


def _outcome(path: Path) -> tuple[str, object]:
    try:
        campaign = read_campaign(path)
    except InputError as error:
        return "error", error.line()
    return "campaign", (
        campaign.orientations.tobytes(),
        campaign.deviations.tobytes(),
        None if campaign.times_s is None else campaign.times_s.tobytes(),
    )


@given(data=mutated())
@example(data=VALID.replace(b"0.00,", b"nan,", 1).replace(b",0.5\n", b",inf\n", 1))  # two bad cells: the same one named
@example(data=VALID + b"\n")  # a blank line at the end: numpy skips it, the row-by-row path reads it
@example(data=VALID.replace(b"A_deg", b"\r_deg", 1))  # a lone carriage return ends a line for the row-by-row path
@example(data=VALID.replace(b"-0.01,", b"-0.0\x1c,", 1))  # numpy reads past a separator control character, float() does not
@SETTINGS
def test_the_plain_path_reads_what_the_row_by_row_path_reads(tmp_path: Path, data: bytes) -> None:
    """numpy's fast reader of plain files gives the same campaign, or the same one-line error, as
    the row-by-row reader every other file goes through."""
    path = tmp_path / "campaign.csv"
    path.write_bytes(data)
    fast = _outcome(path)
    with patch("ph_explorer.io.reader._plain_table", return_value=None):
        assert _outcome(path) == fast
