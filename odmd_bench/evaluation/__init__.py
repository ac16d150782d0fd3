"""Evaluation: metrics, predictions files, scoring, reports and paired comparisons."""
