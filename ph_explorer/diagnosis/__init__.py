"""See where a model fails, find the missing physical effect, add it, and watch the error fall.

results (the record of a diagnosis, typed), within_noise (is a model within noise?), search (which
effect is missing), choice (the chain of effects the search takes), nested (the error of that
choice on rings that took no part in it), evidence and signature (what a candidate, or what is
left, looks like in the head's variables), loop (diagnose, add_effects).
"""

from ph_explorer.diagnosis.candidates import Candidate
from ph_explorer.diagnosis.choice import Choice, choose_effects
from ph_explorer.diagnosis.loop import add_effects, decide, diagnose, repetition_sigma
from ph_explorer.diagnosis.nested import NESTED_FOLDS, nested_after
from ph_explorer.diagnosis.ranking import rank_candidates
from ph_explorer.diagnosis.results import VERDICTS, Diagnosis, NestedAfter, Ring, Step, Verdict
from ph_explorer.diagnosis.search import MATERIAL_REDUCTION, NULL_DRAWS, NULL_MARGIN, CandidateSearch
from ph_explorer.diagnosis.suspect import SuspectRing, suspect_rings
from ph_explorer.diagnosis.within_noise import NoiseTest, within_noise

__all__ = [
    "MATERIAL_REDUCTION",
    "NESTED_FOLDS",
    "NULL_DRAWS",
    "NULL_MARGIN",
    "VERDICTS",
    "Candidate",
    "CandidateSearch",
    "Choice",
    "NestedAfter",
    "Diagnosis",
    "NoiseTest",
    "Ring",
    "Step",
    "SuspectRing",
    "Verdict",
    "add_effects",
    "choose_effects",
    "nested_after",
    "diagnose",
    "decide",
    "within_noise",
    "rank_candidates",
    "repetition_sigma",
    "suspect_rings",
]
