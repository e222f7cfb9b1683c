"""The reliability report (docs/RELIABILITY.md): its suite of campaigns, findings and renderer."""
