"""The vocabulary of a scenario entry that the kinds declared below the scenario layer share.

Every constraint and law kind is declared in its constraint's or law's own module
(cpbc.constraints, cpbc.controllers, cpbc.peers), so the pieces its pydantic spec and its
factory are made of live here, under the constraints: the numbers a scenario writes
(``fields``: finite, expressions of pi, ``Strict``), the names of cases and runs (``names``),
how a ``type:`` is read off a spec (``type_names``), and the checks of numbers against a robot
(``values``). This package depends on numpy, pydantic, cpbc.errors and cpbc.model only.
"""
