"""The closing line of a sweep: wall, CPU and longest job from the jobs' summary.json files."""

import json
import os
import time

from amex.app.progress import describe, duration, summary_stamps, sweep_cost


def _job(sweep, name, wall, cpu, mtime=None):
    path = sweep / name / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"wall_time": wall, "cpu_time": cpu}))
    if mtime is not None:
        os.utime(path, (mtime, mtime))


def test_a_local_sweep_counts_this_process_tree_and_names_its_longest_job(tmp_path):
    _job(tmp_path, "task2_dmp_seed0", 400.0, 1.0)  # an earlier sweep's
    before = summary_stamps(tmp_path)
    _job(tmp_path, "task3_cr_seed0", 96.0, 95.0)
    _job(tmp_path, "task1_dmp_seed0", 5.0, 4.9)
    cost = sweep_cost(tmp_path, before, wall=60.0, local_cpu=117.0)
    assert (cost.jobs, cost.cpu, cost.longest, cost.longest_name) == (
        2,
        117.0,
        96.0,
        "task3_cr_seed0",
    )
    line = describe(tmp_path, cost)
    assert line == (
        f"sweep {tmp_path}: 2 jobs in 1 min 0 s wall, 1 min 57 s CPU (1.95 cores busy on "
        "average), longest job 1 min 36 s (task3_cr_seed0)"
    )


def test_a_cluster_sweep_sums_the_jobs_own_cpu_and_says_so(tmp_path):
    _job(tmp_path, "a", 10.0, 9.5)
    _job(tmp_path, "b", 12.0, 11.5)
    cost = sweep_cost(tmp_path, {}, wall=30.0, local_cpu=3.0, elsewhere=True)
    assert cost.cpu == 21.0
    line = describe(tmp_path, cost)
    assert "21.0 s CPU in the jobs' runs (elsewhere; their start-up not counted)" in line
    assert "cores busy" not in line and line.endswith("longest job 12.0 s (b)")


def test_durations_read_as_people_write_them():
    assert [duration(s) for s in (42.04, 62, 3780, float("nan"))] == [
        "42.0 s",
        "1 min 2 s",
        "1 h 3 min",
        "-",
    ]


def test_one_job_is_one_job(tmp_path):
    _job(tmp_path, "only", 2.0, 1.9)
    line = describe(tmp_path, sweep_cost(tmp_path, {}, wall=2.5, local_cpu=2.2))
    assert line.startswith(f"sweep {tmp_path}: 1 job in 2.5 s wall, 2.2 s CPU"), line


def test_a_clock_step_during_the_sweep_still_counts_its_jobs(tmp_path):
    before = summary_stamps(tmp_path)
    _job(tmp_path, "stepped", 3.0, 2.9, mtime=time.time() - 86400)  # the clock went back a day
    assert sweep_cost(tmp_path, before, wall=4.0, local_cpu=3.0).jobs == 1


def test_a_job_run_again_counts_once_more(tmp_path):
    _job(tmp_path, "again", 3.0, 2.9)
    before = summary_stamps(tmp_path)
    path = tmp_path / "again" / "summary.json"
    path.unlink()
    path.write_text(json.dumps({"wall_time": 1.0, "cpu_time": 0.9}))  # replaced: a new file
    assert sweep_cost(tmp_path, before, wall=2.0, local_cpu=1.0).jobs == 1
