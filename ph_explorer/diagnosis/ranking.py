"""The candidates ranked as one family: what pure noise explains at most over every candidate and
every scanned value sets each one's threshold of "beyond noise" (a look-elsewhere-corrected test),
and the candidates are ordered by how far beyond it each is (docs/diagnosis.md, step 2).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from ph_explorer.blas import in_parts
from ph_explorer.diagnosis.candidates import NULL_MARGIN, Candidate
from ph_explorer.diagnosis.search import CandidateSearch, Scan
from ph_explorer.effects import Effect
from ph_explorer.models.least_squares import Design


def family_levels(scans: Sequence[Scan | Candidate]) -> dict[int, float]:
    """Each tested scan's null level (by id()): the most pure noise explains over the whole family,
    on the scan's own scale (rank_candidates)."""
    # An effect that explains (next to) nothing of pure noise has no free direction left beyond
    # `fixed` and the smoother: it cannot be told from noise at all, and takes no part in the scale.
    tested = [s for s in scans if isinstance(s, Scan) and s.null_best.mean() > 1e-9 * max(s.total, 1e-300)]
    scales = [float(s.null_best.mean()) for s in tested]
    family = max((float((s.null_best / scale).max()) for s, scale in zip(tested, scales)), default=0.0)
    return {id(s): family * scale for s, scale in zip(tested, scales)}


def rank_candidates(
    search: CandidateSearch,
    effects: Sequence[Effect],
    fixed: Design | None = None,
    progress: Callable[[str], None] | None = None,
    beyond_only: bool = False,
) -> list[Candidate]:
    """Every given effect scored, best first: significant ones, then by how far what each explains
    is beyond its threshold of "beyond noise" (NULL_MARGIN times what pure noise explains with its
    own columns and scan), so that of two effects that explain the same, the one with fewer
    columns and scan values comes first. beyond_only: only the candidates some setting of which
    is beyond that threshold, judged without detail (the same ones first: what a pair looks for).

    Look-elsewhere over the whole family: each effect's noise maxima are put on a common scale
    (divided by their mean over the draws); the family's null in each draw is the largest of
    them over every candidate and every scanned value, and a candidate is beyond noise only when
    it explains more than NULL_MARGIN times the largest family null, on its own scale.
    """

    def scanned(effect: Effect) -> Scan | Candidate:
        if progress is not None:
            progress(f"scanning {effect.id}")
        return search.scan(effect, fixed)

    def judged(scan: Scan | Candidate) -> Candidate:
        return scan if isinstance(scan, Candidate) else search.judge(scan, levels.get(id(scan), float("inf")), not beyond_only)

    # Independent scans and judgements, as many at a time as the cores allow (blas.in_parts); one at
    # a time in the calling thread when it is already beside others (a nested fold's).
    scans: list[Scan | Candidate] = in_parts(scanned, effects)
    levels = family_levels(scans)
    if beyond_only:  # judge() finds none of the others beyond noise: their best explains no more than the threshold
        scans = [s for s in scans if isinstance(s, Scan) and s.scanned[0][0] > NULL_MARGIN * levels.get(id(s), float("inf"))]
    out = in_parts(judged, scans)
    out.sort(key=lambda c: (c.significant, c.explained_fraction - NULL_MARGIN * c.noise_fraction), reverse=True)
    return out
