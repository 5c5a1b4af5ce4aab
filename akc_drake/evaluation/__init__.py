"""Experiments reproducing the paper's tables and figures, and the report writer."""
