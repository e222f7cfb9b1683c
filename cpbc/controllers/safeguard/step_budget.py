"""How many torques one guarded step may test: the bound that makes the step's time bounded.

Every test of a candidate torque — the law's, the slide's, each blend, each brake and λ of the
search, the fallback's, the rescue's one-period check — is one prediction of the period and one
evaluation of every guarded margin along it (acceptance.Acceptance.check): 15–40 µs on a
7-joint arm in Python, the unit the guard's time is made of. A step that acts tests 9 of them
at the median on the Panda and up to 19 (the infeasible path, before the rescue's rollouts,
which ``rescue_budget`` bounds). With a budget of K tests a step, the K + 1st raises
:class:`OutOfTests` and the guard holds the last torque that passed the test being run (the
blend's β found so far, the search's λ). The rescue's committed brake, tried as soon as the
law's torque fails (one brake, one test), is tested whatever the budget
(:meth:`StepBudget.uncut`; cut off, it was made, dropped and made again by the step out of
tests). Where none passed yet, the rescue answers first if it holds a committed brake, or at
the motion's first step, where its search runs until rest (Safeguard._out_of_tests); else the
rescue's search (until the arm rests in the model, or within its budget of model periods if it
has one, holding only a brake whose check ended in it), else the uniform brake within the
step's box, untested: the brake whose braking set (S2) keeps the arm
in, which from a state the guard kept in V stops the arm before every configuration boundary,
in the model (cpbc.constraints.stopping). Under a torque-rate limit that brake is reached
into the step's ±ρh box by its nearest acceleration, which can spin a joint riding its rate
bound up through the coupling in D: it is tested against (S0) there, and where it fails the
fallback's brakes reached along the line are held instead (Brakes.spent, up to three tests).
What a budget gives up: a blend nearer the brake than the smallest β, the search of λ cut
short, and the rescue's brakes that need longer than the rescue's budget to stop the arm.

A budget in time does the same on a robot's clock, counting candidates, not tests: a
candidate is the work that makes a torque (the slide's projection, a brake's fit, the blend's
step) and its test, and its time runs from the end of the test before it. A test after the
first (the law's, always tested) begins only where a candidate as long as the step's longest
so far would still end within ``seconds`` of the start of the guard's step (Safeguard.filter);
and a refused torque, which sends the guard to make another candidate, ends the step at once
where one as long would not. The step then holds what a step out of tests holds under a time
budget — the last torque that passed, or the uniform brake untested. Stopping once the budget
was spent let the test under way run past it (the Panda's worst bounded step was 6.4 × its
median, docs/speed.md), and gating the tests alone let the work before the next test — the
slide's 45 µs — run past it. Two things more make what follows the tests part of the budget:
- the slide, whose making (the constraints' gradients, a projection, the margins where the
  arm would stop: 55–125 µs on the Panda, its code cold in the steps that act) costs more
  than a test, begins only where one made as long as the longest of its last few
  (:data:`MADE_KEPT`), and a test as long as the step's longest, end within the budget
  (:meth:`StepBudget.making`);
- under a torque-rate limit what a step out of time holds — the uniform brake's two reaches
  with their F, the one nearer to passing kept to (S0) (Brakes.spent) — is made before the
  candidates once the law's torque fails (:meth:`StepBudget.ahead`,
  :attr:`StepBudget.ready`), not after the budget ran out, where its (S0) tests alone ran up
  to 95 µs past it; each brake made so sets the step's longest candidate, and the step ends
  after them where one as long would not fit.
So a step ends within its budget but for the law's own test, a committed brake's (each always
made), the work made ahead (the two reaches and their F: ~75 µs on the Panda, unbounded
inside the block), and a making or test longer than the ones that foretold it. It reads the clock,
so a run under it is not reproducible; it is for a robot (cpbc.hardware sets it from the
deadline), never simulation's default.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from typing import TypeVar

from cpbc.arrays import Array

#: The makings of one kind whose longest foretells the next (StepBudget.making): the slide's
#: making varies 55–125 µs on the Panda from one step to the next, so the last one alone
#: foretells it poorly; a making a stall of the machine slowed is forgotten after these.
MADE_KEPT = 8
_NOTHING = nullcontext()  # making() without a time budget: no bound, nothing timed
T = TypeVar("T")


class OutOfTests(Exception):  # a signal of the budget, not an error
    """The step has tested as many torques as its budget allows."""


class StepBudget:
    """The tests one step may make, and the last torque that passed one.

    Args:
        tests: K ≥ 1, the most candidate torques one step tests, or None for no bound.
        seconds: the longest one guard step may test torques for, from :meth:`start`
            [s], or None for no bound.

    Attributes:
        used: tests made at this step.
        passed: the last torque that passed its test at this step, or None.
        ready: the torque this step holds if its tests run out before one passes, made
            ahead of its need (Safeguard._before_candidates, under a time budget and a
            torque-rate limit), or None.
        longest: the longest candidate of this step whose test was exact, its making and
            its test [s] (timed under a time budget only; a slide's making is kept apart,
            :meth:`making`).
        spent: steps that ran out of tests.
    """

    def __init__(self, tests: int | None, seconds: float | None = None) -> None:
        if tests is not None and tests < 1:
            raise ValueError(f"tests: a step tests at least the law's torque (≥ 1), got {tests}")
        if seconds is not None and not seconds > 0.0:
            raise ValueError(f"seconds: give a time > 0 [s], got {seconds}")
        self.tests = tests
        self.seconds = seconds
        self._until = float("inf")
        self.used = 0
        self.passed: Array | None = None
        self.ready: Array | None = None
        self.longest = 0.0
        self._mark = 0.0  # the end of the step's last test (or its beginning)
        self.spent = 0
        self._uncut = False  # inside uncut(): tests count, none is cut off
        self._ahead = False  # inside ahead(): no bound, each test's time sets ``longest``
        self._made: dict[str, deque[float | None]] = {}  # each kind's last makings [s]
        # the blocks, made once: a generator's context costs 5-12 µs in a step that acts
        # after calm ones (its code cold), four of them a step there
        self._lifted, self._uncut_block, self._ahead_block, self._making = (
            _Lifted(self), _Uncut(self), _Ahead(self), _TimedMaking(self))

    def start(self) -> None:
        """The guarded call begins: its time is counted from now."""
        if self.seconds is not None:
            self._until = time.perf_counter() + self.seconds

    @property
    def timed(self) -> bool:
        """The step has a budget in time."""
        return self.seconds is not None

    def begin(self) -> None:
        """A new step: no test made yet."""
        self.used, self.passed, self.ready, self.longest = 0, None, None, 0.0
        if self.seconds is not None:
            self._mark = time.perf_counter()

    def lifted(self) -> AbstractContextManager[None]:
        """No bound inside the block (for F made there): the rescue's own check, which its
        own budget bounds, and the warm-up of every path. Blocks nest."""
        return self._lifted

    def uncut(self) -> AbstractContextManager[None]:
        """Tests inside the block count, but none is cut off: the rescue's committed brake,
        the one candidate a step out of tests would still make (Safeguard._out_of_tests).
        Under a time budget, a refused torque then ends the step where a candidate as long
        as the step's longest would not end within it (:meth:`counted`), and the next
        candidate's time runs from the block's end."""
        return self._uncut_block

    def making(self, kind: str) -> AbstractContextManager[None]:
        """The block makes a candidate of ``kind`` whose making costs more than a test (the
        slide): under a time budget the step ends before it where making one as long as the
        last of its kind, and a test as long as the step's longest, would not end within the
        budget; the block's time is then that kind's. Without one, nothing is done."""
        if self._until == float("inf"):
            return _NOTHING
        making = self._making
        making.kind = kind
        return making

    def ahead(self) -> AbstractContextManager[None]:
        """What a spent step would hold, made inside the block before the step's next
        candidate (:attr:`ready`): no bound inside it, and under a time budget the step ends
        after it where a candidate as long as the step's longest would not end within the
        budget, the next candidate's time running from the block's end. The brakes made
        inside are candidates as a later one would be: each one's making and test sets the
        step's longest (:meth:`counted`), a sign's test too (it can only raise it). Without
        them the step's longest after the block was 0 where the law's test was a sign (on the
        Panda, most steps that act under a rate limit), and the next candidate began however
        little time was left: a slide begun 120–144 µs into a 150 µs budget ended at 260–300.
        """
        return self._ahead_block

    def _block_ended(self, goes_on: bool) -> None:
        """After :meth:`uncut`'s or :meth:`ahead`'s block, under a time budget: the next
        candidate's time runs from now, and where the step ``goes_on`` to another candidate
        it ends here (OutOfTests) unless one as long as its longest would end within the
        budget."""
        if self._until < float("inf"):
            now = self._mark = time.perf_counter()
            if goes_on and now + self.longest > self._until:
                raise OutOfTests

    def counted(self, slack: Callable[[Array], float],
                exact: bool = True) -> Callable[[Array], float]:
        """``slack`` that counts its calls against the budget and remembers the last torque
        that passed (F ≥ 0); raises :class:`OutOfTests` past the budget. Without a bound,
        ``slack`` itself. A test that is not ``exact`` (the first test's sign from bounds,
        Acceptance.check) is not the time a later candidate is taken to need: it comes first
        in the step, so the exact test after it begins well inside the budget and sets it."""
        if self._uncut:
            return lambda t: self._test(slack, t)
        if self._ahead and self.seconds is not None:
            return self._timed_ahead(slack)
        until = self._until
        if until < float("inf"):
            return self._timed(slack, until, exact)
        if self.tests is None:
            return slack
        most = self.tests

        def counted(t: Array) -> float:
            if self.used >= most:  # past it too: an uncut block's tests count
                raise OutOfTests
            return self._test(slack, t)

        return counted

    def _timed(self, slack: Callable[[Array], float], until: float,
               exact: bool) -> Callable[[Array], float]:
        """``counted`` under a time budget ending at ``until`` (perf_counter) as well."""
        most = self.tests if self.tests is not None else sys.maxsize

        def timed(t: Array) -> float:
            begun = time.perf_counter()
            # the first test (the law's torque) is always made; a later one only where a
            # candidate as long as this step's longest would still end within the budget
            if self.used >= most or (self.used and begun + self.longest > until):
                raise OutOfTests
            f = self._test(slack, t)
            ended = time.perf_counter()
            if exact:
                self.longest = max(self.longest, ended - self._mark)
            self._mark = ended
            if f < 0.0 and ended + self.longest > until:  # before the next candidate's work
                raise OutOfTests
            return f

        return timed

    def uncounted(self, test: Callable[[Array], T]) -> Callable[[Array], T]:
        """``test`` made where no bound applies (:meth:`lifted`): inside :meth:`ahead`
        under a time budget timed as :meth:`counted` times it there, else itself."""
        if self._ahead and self.seconds is not None:
            return self._timed_ahead(test)
        return test

    def _timed_ahead(self, slack: Callable[[Array], T]) -> Callable[[Array], T]:
        """``slack`` inside :meth:`ahead` under a time budget: uncounted and never cut off,
        its time since the test before it (the candidate's making and test) sets
        :attr:`longest`."""

        def timed(t: Array) -> T:
            f = slack(t)
            ended = time.perf_counter()
            self.longest = max(self.longest, ended - self._mark)
            self._mark = ended
            return f

        return timed

    def _test(self, slack: Callable[[Array], float], t: Array) -> float:
        """One counted test of ``t``."""
        self.used += 1
        f = slack(t)
        if f >= 0.0:
            self.passed = t
        return f


class _Lifted:
    """StepBudget.lifted's block: no bound inside, the bounds before it restored after."""

    __slots__ = ("_budget", "_saved")

    def __init__(self, budget: StepBudget) -> None:
        self._budget, self._saved = budget, list[tuple[int | None, float]]()

    def __enter__(self) -> None:
        budget = self._budget
        self._saved.append((budget.tests, budget._until))
        budget.tests, budget._until = None, float("inf")

    def __exit__(self, *raised: object) -> None:
        budget = self._budget
        budget.tests, budget._until = self._saved.pop()


class _Uncut:
    """StepBudget.uncut's block."""

    __slots__ = ("_before", "_budget")

    def __init__(self, budget: StepBudget) -> None:
        self._budget, self._before = budget, list[Array | None]()

    def __enter__(self) -> None:
        self._before.append(self._budget.passed)
        self._budget._uncut = True

    def __exit__(self, raised: type[BaseException] | None, *rest: object) -> None:
        budget = self._budget
        budget._uncut = False
        before = self._before.pop()
        if raised is None:
            budget._block_ended(budget.passed is before and budget.used > 0)


class _Ahead:
    """StepBudget.ahead's block: lifted, each test timed; the step may end after it."""

    __slots__ = ("_budget",)

    def __init__(self, budget: StepBudget) -> None:
        self._budget = budget

    def __enter__(self) -> None:
        budget = self._budget
        budget._lifted.__enter__()
        budget._ahead = True

    def __exit__(self, raised: type[BaseException] | None, *rest: object) -> None:
        budget = self._budget
        budget._ahead = False
        budget._lifted.__exit__()
        if raised is None:
            budget._block_ended(True)


class _TimedMaking:
    """StepBudget.making's block under a time budget, for the ``kind`` set before it (one
    block at a time: makings do not nest)."""

    __slots__ = ("_begun", "_budget", "kind")

    def __init__(self, budget: StepBudget) -> None:
        self._budget, self.kind, self._begun = budget, "", 0.0

    def __enter__(self) -> None:
        budget = self._budget
        made = budget._made.setdefault(self.kind, deque(maxlen=MADE_KEPT))
        self._begun = begun = time.perf_counter()
        # a kind not made of late is taken to be made as fast as the step's longest test
        known = [t for t in made if t is not None]
        if begun + max(known, default=budget.longest) + budget.longest > budget._until:
            made.append(None)  # refused, it ages the record as a making does: a making a
            raise OutOfTests   # stall slowed past the budget does not bar its kind for good

    def __exit__(self, raised: type[BaseException] | None, *rest: object) -> None:
        if raised is None:
            budget = self._budget
            budget._mark = ended = time.perf_counter()  # the next test's candidate: its test
            budget._made[self.kind].append(ended - self._begun)
