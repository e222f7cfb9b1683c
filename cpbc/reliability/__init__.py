"""Reliability campaigns: what holds outside the proofs (sampled data, model mismatch, noise,
torque limits, bad input, long runs). ``tools/reliability_report.py`` runs them and writes
docs/RELIABILITY.md."""
