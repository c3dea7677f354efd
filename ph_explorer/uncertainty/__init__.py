"""Uncertainty: adaptive Monte Carlo, a model's bands with every component, a task's U, models'
out-of-sample error, parameters' jackknife uncertainty and their spread as curves.

Method: docs/uncertainty.md.
"""
