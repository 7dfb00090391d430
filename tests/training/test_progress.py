"""The progress reporter's TensorBoard scalars: against the run's env steps, not its iterations."""

import io

from league.core.schedule import PhaseState
from league.training.progress import BudgetClock, ProgressReporter, budget_left
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


def test_budget_left_says_the_share_done_and_the_time_left_at_the_given_speed():
    assert budget_left(2_000_000, 5_000_000, 10_000.0) == "40% of 5,000,000, 5 min left"  # 3,000,000 left at 10,000/s
    assert budget_left(0, 36_000_000, 5_000.0) == "0% of 36,000,000, 2 h 00 min left"
    assert budget_left(4_990_000, 5_000_000, 1_000.0) == "100% of 5,000,000, 10 s left"
    assert budget_left(1_000, 4_000, float("nan")) == "25% of 4,000"  # no speed yet: no time left


def test_budget_clock_counts_earlier_phases_whole_and_averages_the_recent_speed():
    budgets = [20_480, 40_960]  # 61,440 in all
    started = BudgetClock(budgets)
    # the first iteration of a new run: its own 8,192 env steps in 2 s, 53,248 left at 4,096/s
    assert started.line(PhaseState(0, "attacker", 0, env_steps=8_192), 8_192, 2.0, now=100.0) == "13% of 61,440, 13 s left"
    # the phase ends early (on its win rate): its unplayed 12,288 steps are done, not left
    assert started.line(PhaseState(1, "team", 2, env_steps=8_192), 8_192, 9.0, now=102.0) == "47% of 61,440, 8 s left"  # 32,768 left at 4,096/s

    resumed = BudgetClock(budgets)  # resumed in phase 2 with 8,192 of its steps played before the resume
    assert resumed.line(PhaseState(1, "team", 2, env_steps=16_384), 8_192, 1.0, now=50.0) == "60% of 61,440, 3 s left"
    # the next line: 8,192 more in 3 s of wall time since the last line; 16,384 in 4 s over both, 16,384 left
    assert resumed.line(PhaseState(1, "team", 2, env_steps=24_576), 8_192, 0.1, now=53.0) == "73% of 61,440, 4 s left"


def iteration_record(phase, steps, env_steps):
    train = TrainResult([], env_steps, {}, {}, {}, seconds=1.0, learning_seconds=0.5)
    return IterationRecord(
        1, phase, train, steps=steps, env_steps=env_steps, episodes=10, snapshots=[], snapshot_names=[],
        evaluation=[], curves=None, weights={}, timing=IterationTiming(sampling=1.5, learning=0.5, evaluation=2.0),
        league_size=3, checkpoint=None,
    )


def test_the_iteration_line_ends_with_the_share_of_the_runs_budget_and_the_time_left(tmp_path):
    stream = io.StringIO()
    progress = ProgressReporter(tmp_path, 2, stream=stream, phase_budgets=[1_000_000, 3_000_000])
    # resumed in phase 2: 1,000,000 + 400,000 of 4,000,000 done; 8,192 steps in 4 s of training and evaluation
    progress.iteration(iteration_record(PhaseState(1, "team", 5, episodes=10, env_steps=400_000), 8_192, 1_400_000))
    progress.close()
    assert stream.getvalue().rstrip().endswith("| league 3 | 35% of 4,000,000, 21 min left")  # 2,600,000 at 2,048/s

    stream = io.StringIO()
    progress = ProgressReporter(tmp_path, 2, stream=stream)  # a phase that ends after its episodes: no budget known
    progress.iteration(iteration_record(PhaseState(1, "team", 5, episodes=10, env_steps=400_000), 8_192, 1_400_000))
    progress.close()
    assert stream.getvalue().rstrip().endswith("| league 3")
