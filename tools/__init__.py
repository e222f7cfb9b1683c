"""Tools of this repository (not shipped in the wheel): the reliability report's campaigns
and its Markdown generator. Run from the repository's root."""
