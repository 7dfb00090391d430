"""What the tests of the study benches (``bench/league_quality.py``, ``bench/exploitability_curve.py``) share:
loading a bench script as a module, and ``league.exploit`` run in the test's process."""

import contextlib
import importlib.util
import io
import json
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench"


@contextlib.contextmanager
def bench_module(name: str):
    """``bench/NAME.py`` imported as the module ``NAME`` for the block."""
    spec = importlib.util.spec_from_file_location(name, BENCH / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules[spec.name]


def exploit_here(argv):
    """``league.exploit`` in this process, on the test module's Ray instance: what a study's own process would print
    (``league.studies.exploitation.run_exploit`` runs it in a process of its own, which costs a test 10 s a call)."""
    from league import exploit

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert exploit.main(argv) == 0
    return json.loads(out.getvalue())
