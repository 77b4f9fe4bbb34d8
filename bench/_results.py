"""Shared by the benchmark scripts: write a results dict to bench/results/<name>.json."""

import json
from pathlib import Path


def write_results(name: str, results: dict) -> Path:
    path = Path(__file__).resolve().parent / "results" / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {path}")
    return path
