"""What watches a `TimeStepper`: an observer is told when the initial state is set, after every step and when the
caller finishes, and reads what it needs from the stepper (its time, its state, its ledger)."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

__all__ = ["Observer"]


@runtime_checkable
class Observer(Protocol):
    """An object attached to a `TimeStepper` (``stepper.attach(observer)``). Each method is optional: the stepper
    calls the ones an observer has, in the order the observers were attached.

    * ``started(stepper)``: the initial state is set (step 0), or set again by a restart;
    * ``stepped(stepper)``: one step was taken and booked (``stepper.step``, ``stepper.t``, the state);
    * ``finished(stepper)``: the caller has finished with the stepper (``stepper.finish()``).
    """
