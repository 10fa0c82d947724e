"""``imitate eval``: a run's learned model reproduced in the variations of a suite.

Writes under ``RUN_DIR/eval/``: ``results.jsonl`` (one record per variation, appended and
synced as each finishes, with the suite digest and the exact settings), ``summary.json``,
``outcomes.png`` and ``report.html`` (of the last evaluation) and
``failures/<digest>/<id>-<outcome>.mp4`` for the first failures. An interrupted
evaluation continues where it stopped: variations whose id already has a record under the same
digest (suite, seed, learned model) are not run again.
"""

from __future__ import annotations

import json
import os
import time
from contextlib import closing
from pathlib import Path

from tqdm import tqdm

from imitate import plots, provenance, report_html
from imitate.artifacts import load_npz, save_json
from imitate.errors import ImitateError
from imitate.evaluation.parallel import run_local, run_ray
from imitate.evaluation.report import failure_video, plot_outcomes, summarize
from imitate.evaluation.suite import Suite
from imitate.evaluation.variation import draw, path_points
from imitate.learning import LearnedModel

__all__ = ["evaluate", "last_records", "read_records"]

RESULTS = "results.jsonl"


def evaluate(
    run_dir: Path,
    suite: Suite,
    *,
    n: int | None = None,
    seed: int = 0,
    workers: int | None = None,
    ray: str | None = None,
    videos: int = 3,
    progress: bool | None = None,
) -> dict:
    """Evaluate ``run_dir``'s ``model.npz`` on ``n`` variations of ``suite`` (default: its
    ``variations``) drawn with ``seed``, on ``workers`` local processes (default: every core) or
    on Ray (``ray``: an address or ``"auto"``); videos of the first ``videos`` failures.
    ``progress``: tqdm's ``disable`` inverted (``None``: on a terminal). Returns the summary.

    Raises:
        ImitateError: a missing or corrupt model, ``n`` or ``workers`` below 1, Ray unusable.
    """
    run_dir, n = Path(run_dir), suite["variations"] if n is None else n
    workers = (os.cpu_count() or 1) if workers is None else workers
    for flag, value in (("--n", n), ("--workers", workers)):
        if value < 1:
            raise ImitateError(f"{flag} {value} not accepted: at least 1")
    model_path = run_dir / "model.npz"
    stored = load_npz(model_path, required=(*LearnedModel.array_names(), "gaze"))
    arrays = {k: stored[k] for k in (*LearnedModel.array_names(), "gaze")}
    learned = LearnedModel.from_arrays(arrays)
    digest = suite.digest(seed, model_path.read_bytes(), provenance.code_digest())
    out = run_dir / "eval"
    out.mkdir(parents=True, exist_ok=True)
    path = path_points(learned, arrays["gaze"], suite["max_iter"])
    variations = [draw(suite, seed, i, path) for i in range(n)]
    records = {r["id"]: r for r in read_records(out / RESULTS, digest) if r["id"] < n}
    pending = [v for v in variations if v.id not in records]
    start, load = time.perf_counter(), os.getloadavg()
    finished = (
        run_ray(arrays, pending, ray) if ray else run_local(arrays, pending, min(workers, n))
    ) if pending else (record for record in ())
    _end_line(out / RESULTS)
    # closing: an interruption stops the workers before it propagates
    with closing(finished), open(out / RESULTS, "a") as results, tqdm(
        total=n, initial=n - len(pending), desc="eval", unit="variation",
        disable=None if progress is None else not progress,
    ) as bar:
        for result in finished:
            record = {"digest": digest, **result}
            results.write(json.dumps(record) + "\n")
            results.flush()
            os.fsync(results.fileno())
            records[record["id"]] = record
            bar.set_postfix(outcome=record["outcome"])
            bar.update()
    wall = time.perf_counter() - start
    ordered = [records[i] for i in sorted(records)]
    summary = {
        "suite_digest": digest, "seed": seed, "suite": suite.to_json(),
        "path_points": len(path), **summarize(ordered),
        "run": {
            "ran": len(pending), "wall_seconds": wall, "backend": "ray" if ray else "local",
            "workers": None if ray else min(workers, n),
            "load_average_start": list(load), "load_average_end": list(os.getloadavg()),
        },
    }
    save_json(out / "summary.json", summary)
    plots.save(plot_outcomes(ordered, path), out / "outcomes.png")
    failures = [r for r in ordered if r["outcome"] != "success"][:videos]
    for record in tqdm(failures, desc="failure videos", unit="video", disable=not progress):
        video = out / "failures" / digest / f"{record['id']:04d}-{record['outcome']}.mp4"
        if not video.exists():
            failure_video(video, learned, arrays["gaze"], record)
    report_html.save_eval_page(out, summary)
    return summary


def read_records(path: Path, digest: str) -> list[dict]:
    """The records of ``path`` (``results.jsonl``) with ``digest``, the last one per id; a
    line cut short by an interruption is skipped."""
    records = {}
    if not path.exists():
        return []
    for line in path.read_text().splitlines():
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            continue
        if record.get("digest") == digest:
            records[record["id"]] = record
    return list(records.values())


def last_records(run_dir: Path) -> list[dict]:
    """The records of the last evaluation of ``run_dir`` (the digest in its
    ``eval/summary.json``), sorted by id.

    Raises:
        ImitateError: ``run_dir`` has no evaluation.
    """
    out = Path(run_dir) / "eval"
    if not (out / "summary.json").is_file():
        raise ImitateError(f"{out / 'summary.json'} is missing: run `imitate eval {run_dir}` first")
    digest = json.loads((out / "summary.json").read_text())["suite_digest"]
    return sorted(read_records(out / RESULTS, digest), key=lambda r: r["id"])


def _end_line(path: Path) -> None:
    """End a line cut short by an interruption, so the next record starts on its own."""
    if path.exists() and path.stat().st_size:
        with open(path, "rb+") as f:
            f.seek(-1, os.SEEK_END)
            if f.read(1) != b"\n":
                f.write(b"\n")
