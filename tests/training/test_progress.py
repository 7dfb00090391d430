"""The progress reporter's TensorBoard scalars: against the run's env steps, not its iterations."""

import io

from league.core.schedule import PhaseState
from league.training.progress import ProgressReporter
from league.training.records import IterationRecord, IterationTiming, TrainResult


class Recorder:
    def __init__(self):
        self.scalars = []

    def add_scalar(self, tag, value, step):
        self.scalars.append((tag, value, step))

    def flush(self):
        pass

    def close(self):
        pass


def test_scalars_are_written_against_the_runs_env_steps(tmp_path):
    progress = ProgressReporter(tmp_path, 2, stream=io.StringIO())
    progress.writer.close()
    progress.writer = recorder = Recorder()
    phase = PhaseState(index=0, side="attacker", start_iteration=0, episodes=10, learner_wins=4)
    for iteration, env_steps in ((1, 8192), (2, 16384)):
        train = TrainResult([], env_steps, {}, {}, {}, seconds=1.0, learning_seconds=0.5)
        progress.iteration(IterationRecord(
            iteration, phase, train, steps=8192, env_steps=env_steps, episodes=10, snapshots=[], snapshot_names=[],
            evaluation=[], curves=None, weights={}, timing=IterationTiming(sampling=0.5, learning=0.5, evaluation=0.0),
            league_size=3, checkpoint=None,
        ))
    steps = {tag: [step for t, _, step in recorder.scalars if t == tag] for tag, _, _ in recorder.scalars}
    assert steps["perf/sps"] == [8192, 16384]
    assert steps["league/attacker_phase_win_rate"] == [8192, 16384]
    assert [value for tag, value, _ in recorder.scalars if tag == "perf/iteration"] == [1.0, 2.0]


def test_every_progress_line_is_kept_in_the_run_directory_across_a_resume(tmp_path):
    for text in ("run directory (new)", "run directory (resumed at iteration 7)"):
        progress = ProgressReporter(tmp_path, 2, stream=io.StringIO())
        progress.message(text)
        progress.close()
    lines = (tmp_path / "run.log").read_text().splitlines()
    assert [line.split(" ", 2)[2] for line in lines] == ["run directory (new)", "run directory (resumed at iteration 7)"]
