"""See where a model fails, find the missing physical effect, add it, and watch the error fall.

results (what a diagnosis finds, as data), search (which effect is missing), evidence (a
candidate's signature binned against its own variable), loop (diagnose, add_effects).
"""

from ph_explorer.diagnosis.loop import add_effects, decide, diagnose, repetition_sigma
from ph_explorer.diagnosis.noise_test import NoiseTest, within_noise
from ph_explorer.diagnosis.results import VERDICTS, Candidate, Diagnosis, Step, signature_text, verdict_text
from ph_explorer.diagnosis.search import MATERIAL_REDUCTION, NULL_DRAWS, NULL_MARGIN, CandidateSearch, rank_candidates

__all__ = [
    "MATERIAL_REDUCTION",
    "NULL_DRAWS",
    "NULL_MARGIN",
    "VERDICTS",
    "Candidate",
    "CandidateSearch",
    "Diagnosis",
    "NoiseTest",
    "Step",
    "add_effects",
    "diagnose",
    "decide",
    "signature_text",
    "verdict_text",
    "within_noise",
    "rank_candidates",
    "repetition_sigma",
]
