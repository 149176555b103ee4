"""The energy balance's round-off against the step count (docs/explanation/reliability.md, "The discrete energy balance").

Example 1's shape at a small nx with more and more steps: the measured relative residual, the round-off estimate
u·n·|η|/(|v|·Δt) of `run.checks.roundoff_growth` (without its safety factor), their ratio, and the tolerance the
check uses; and the same residual with every ledger term summed by math.fsum (compensated), which shows that the
summation is not where the round-off comes from.

    .venv/bin/python benchmarks/bench_balance_roundoff.py [--nx 50] [--nt 20000 100000 200000]
    .venv/bin/python benchmarks/bench_balance_roundoff.py --nx 5000 20000 50000 100000 --nt 1500   # the Courant number
"""

from __future__ import annotations

import argparse
import math

import stringcontact as sc
from stringcontact.core import ledger, stepper
from stringcontact.run import checks


class _FsumLedger(ledger.EnergyLedger):
    """The ledger with each cumulative term an exact sum (math.fsum over every step's term)."""

    def __init__(self, start, conservative, **kwargs):
        super().__init__(start, conservative, **kwargs)
        self.parts = ([], [], [], [])

    def add(self, terms, slack=0.0):
        for part, value in zip(self.parts, terms[2:6]):
            part.append(value)
        return super().add(terms, slack)

    @property
    def cumulative(self):
        return (self.kin, self.el, *(math.fsum(p) for p in self.parts))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--nx", type=int, nargs="+", default=[50])
    parser.add_argument("--nt", type=int, nargs="+", default=[20000, 100000, 200000])
    args = parser.parse_args()
    print("nx,nt,relative_residual,relative_residual_fsum,estimate,ratio,tolerance")
    plain = stepper.EnergyLedger
    for nx, nt in ((nx, nt) for nx in args.nx for nt in args.nt):
        scene = sc.load_scene("example1").replace(nx=nx, nt=nt)
        res = sc.simulate(scene, output=sc.Output(progress=False))
        stepper.EnergyLedger = _FsumLedger
        try:
            exact = sc.simulate(scene, output=sc.Output(progress=False))
        finally:
            stepper.EnergyLedger = plain
        b = checks.energy_balance(res)
        estimate = checks.roundoff_growth(res) * 1e-8 / checks.ROUNDOFF_FACTOR
        print(f"{nx},{nt},{b['relative_residual']:.3g},{checks.energy_balance(exact)['relative_residual']:.3g},"
              f"{estimate:.3g},{b['relative_residual'] / estimate:.3g},{b['tolerance']:.3g}")


if __name__ == "__main__":
    main()
