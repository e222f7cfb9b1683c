"""The reliability report (docs/ROBUSTNESS.md): its suite of campaigns, findings and renderer."""
