"""Which rings to measure: a campaign's design, and the next rings given what is measured.

Method: docs/planning.md.
"""
