"""Figures as data and SVG: polar roundness charts, the A x B error map, the charts of the
diagnosis, and the self-contained HTML report. Nothing here draws on screen.

Method: docs/explorer.md.
"""
