"""``league.run --run-dir`` where no directory can be made: one line naming the path and why, exit 2,
nothing written (checked before Ray or torch start, so in this process)."""

import os

import pytest

from league import run

TINY = """
name: tiny
ppo: {train_batch_size: 200, minibatch_size: 100, num_epochs: 1, hidden: [16]}
resources: {num_cpus: 1, num_env_runners: 0}
"""


def files_under(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.fixture
def config(tmp_path):
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY)
    (tmp_path / "README.md").write_text("a file, not a folder\n")
    return str(path)


@pytest.mark.parametrize("under", ["README.md/sub", "README.md/a/b"])
def test_a_run_dir_under_a_file_is_one_line_naming_it(tmp_path, config, capsys, under):
    before = files_under(tmp_path)
    assert run.main(["--config", config, "--run-dir", str(tmp_path / under)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [
        f"error: cannot create the run directory {tmp_path / under}: {tmp_path / 'README.md'} is a file, not a directory"
    ]
    assert files_under(tmp_path) == before


def test_folders_made_before_the_failure_are_removed(tmp_path, config, capsys):
    before = files_under(tmp_path)
    name = "x" * (os.pathconf(tmp_path, "PC_NAME_MAX") + 1)  # the last folder cannot be made
    run_dir = tmp_path / "made" / "too" / name
    assert run.main(["--config", config, "--run-dir", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith(f"error: cannot create the run directory {run_dir}: ")
    assert "name too long" in err.lower()
    assert files_under(tmp_path) == before
