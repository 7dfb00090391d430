"""The learner's loss compiled (``ppo.compile_loss``): a run stays one run, and one killed and
resumed (its loss compiled again in the new process) ends as the run never killed."""

from league.rllib.compat import inductor_compiler_found
from league.state.run_dir import run_differences
from tests.training.test_same_seed import TINY_SMOKE, finish, iterations, killed_after_two_and_resumed, league

TINY_COMPILED = [*TINY_SMOKE, "--set", "ppo.compile_loss=true"]


def test_a_compiled_loss_run_killed_and_resumed_is_the_run_never_killed(tmp_path):
    out = finish(league(*TINY_COMPILED, "--run-dir", str(tmp_path / "whole")))
    said = ("the learner's loss is compiled" if inductor_compiler_found()
            else "torch finds no C++ compiler to build kernels with; the loss runs eagerly")
    assert f"ppo.compile_loss: {said}" in out, out[-2000:]
    assert iterations(tmp_path / "whole") >= 4
    killed_after_two_and_resumed(TINY_COMPILED, tmp_path / "whole", tmp_path / "killed")
    assert run_differences(tmp_path / "whole", tmp_path / "killed") == []
