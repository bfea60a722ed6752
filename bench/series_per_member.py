"""What a job over every field of a series costs per field, against the algorithm's own run
phase: (total - load - partition) / n of one `actopo-bench --scalars all` process, against the
mean `times_s.run` of n single-field processes; medians of --repeats. Also each field's own
share alone (its preprocess, run and results in the many-field process, without the structure's
one-time preprocessing, which a single-field run counts outside its run phase too).

    .venv/bin/python bench/series_per_member.py --mesh ../shared/data/isabel_series_s2_tet.vtu \\
        --algorithm persistence-diagram --structure actopo
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", required=True)
    parser.add_argument("--algorithm", default="persistence-diagram")
    parser.add_argument("--structure", default="actopo")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--bench", default=str(ROOT / "build/server/cmd/actopo-bench"))
    args = parser.parse_args()

    def run(*flags: str) -> dict[str, Any]:
        out = subprocess.run([args.bench, "--mesh", args.mesh, "--algorithm", args.algorithm,
                              "--structure", args.structure, "--json", *flags],
                             check=True, capture_output=True, text=True).stdout
        return json.loads(out)

    many, fields_only, single = [], [], []
    for _ in range(args.repeats):
        report = run("--scalars", "all")
        fields = [entry["scalar"] for entry in report["fields"]]
        times = report["times_s"]
        many.append((times["total"] - times["load"] - times["partition"]) / len(fields))
        fields_only.append(statistics.mean(sum(entry["times_s"].values())
                                           for entry in report["fields"]))
        single.append(statistics.mean(run("--scalar", f)["times_s"]["run"] for f in fields))
    per_member, per_field, own = (statistics.median(x) for x in (many, fields_only, single))
    print(json.dumps({"algorithm": args.algorithm, "structure": args.structure,
                      "per_member_s": per_member, "per_field_own_work_s": per_field,
                      "own_run_s": own, "ratio": per_member / own,
                      "field_work_ratio": per_field / own, "per_member_runs": many,
                      "per_field_runs": fields_only, "own_run_runs": single}, indent=1))


if __name__ == "__main__":
    main()
