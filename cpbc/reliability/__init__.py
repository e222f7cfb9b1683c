"""Reliability campaigns: what holds outside the proofs (sampled data, model mismatch, noise,
torque limits, bad input, long runs). ``python -m cpbc.verify`` runs the sampled-state
campaigns of any scenario (docs/RELIABILITY.md); ``tools/reliability_report.py`` runs the
robustness sections and writes docs/ROBUSTNESS.md."""
