"""Each filter kernel is compiled once per run type, not once per literal constant.

Numba compiles a jitted callee again for every ``Literal[int]`` a caller passes it (a literal
``0`` before a loop widens the type, a literal ``1`` for the KF's one member per run): each
such copy is seconds of a user's first run (``benchmarks/bench_first_run.py --kernels``). A
closed-loop Monte Carlo of a shipped plan with every filter, in a fresh process, must leave
every kernel of :mod:`obsplan.estimation.kernels` and
:mod:`obsplan.estimation.montecarlo.loop_kernels` with one signature.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

#: compiles every kernel (about a minute): the slow tier
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]

CODE = """
import json
import numba
import obsplan
from obsplan.estimation import kernels
from obsplan.estimation.montecarlo import loop_kernels
from obsplan.planning.problem.parse import LOCALISE_PROBLEM

pb = obsplan.load_problem(LOCALISE_PROBLEM).with_changes(
    horizon={"steps": 40}, objective={"starts": 1}
)
r = obsplan.plan(pb, runs=2, max_runs=2, processes=1)
sigs = {}
for mod in (kernels, loop_kernels):
    for name, obj in vars(mod).items():
        if isinstance(obj, numba.core.registry.CPUDispatcher) and obj.signatures:
            sigs[f"{mod.__name__}.{name}"] = [str(s) for s in obj.signatures]
print(json.dumps(sigs))
"""


def test_every_kernel_has_one_signature_after_a_closed_loop_monte_carlo(tmp_path):
    # an empty numba cache: every kernel is compiled (one loaded from a cache hides its callees)
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path))
    proc = subprocess.run(
        [sys.executable, "-c", CODE], env=env, capture_output=True, text=True, timeout=900
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    sigs = json.loads(proc.stdout.strip().splitlines()[-1])
    assert "obsplan.estimation.kernels.record_batch" in sigs  # the run used the kernels
    many = {k: v for k, v in sigs.items() if len(v) > 1}
    assert not many, json.dumps(many, indent=1)
