"""orchestrator.studies.study: tasks in worker processes, recorded one JSON line each, resumed without running again."""
import json
import time

from orchestrator.studies.study import Study

TASKS = ['{"x": 1}', '{"x": 2.5, "y": [1, 2]}', "not JSON"]


def test_a_study_runs_every_task_records_it_and_reports_a_failure_as_a_result(tmp_path):
    path = tmp_path / "study.jsonl"
    results = Study(path).run(TASKS, json.loads, jobs=2)
    assert results[TASKS[0]] == {"x": 1} and results[TASKS[1]] == {"x": 2.5, "y": [1, 2]}
    assert results[TASKS[2]]["error"].startswith("JSONDecodeError: ")
    records = [json.loads(line) for line in path.read_text().splitlines()]
    assert sorted(r["task"] for r in records) == sorted(repr(t) for t in TASKS)


def test_a_resumed_study_reads_the_recorded_tasks_back_and_runs_only_the_new_ones(tmp_path):
    path = tmp_path / "study.jsonl"
    Study(path).run(TASKS[:2], json.loads, jobs=1)
    # run again, a task would get `str`'s result (its own text) instead of the recorded one
    results = Study(path, resume=True).run([*TASKS[:2], '{"z": 3}'], json.loads, jobs=1)
    assert results == {TASKS[0]: {"x": 1}, TASKS[1]: {"x": 2.5, "y": [1, 2]}, '{"z": 3}': {"z": 3}}
    again = Study(path, resume=True).run(TASKS[:2], str, jobs=1)
    assert again == {TASKS[0]: {"x": 1}, TASKS[1]: {"x": 2.5, "y": [1, 2]}}
    assert Study(path).run(TASKS[:1], json.loads, jobs=1) == {TASKS[0]: {"x": 1}}   # not resumed: afresh
    assert len(path.read_text().splitlines()) == 1


def _sleep(seconds):
    time.sleep(seconds)
    return {}


def test_a_resumed_study_keeps_the_wall_time_of_its_recorded_runs(tmp_path):
    """The report of a re-rendered study states how long its runs took, not how long the re-render took:
    the span from the first recorded task's start to the last one's end, read back from the record."""
    path = tmp_path / "study.jsonl"
    study = Study(path)
    study.run([0.3], _sleep, jobs=1)
    assert study.wall_time >= 0.3
    assert Study(path, resume=True).wall_time == study.wall_time
    assert Study(path).wall_time is None   # afresh: nothing recorded yet
