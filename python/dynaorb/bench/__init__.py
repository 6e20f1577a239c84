"""Benchmarks: speed measured as medians, written as JSON and a Markdown table."""
