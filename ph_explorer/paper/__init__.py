"""The paper's two models trained together, and its Tables 1-3 at held-out orientations.

Method: docs/models.md.
"""
