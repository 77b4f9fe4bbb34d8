"""Snakemake adapter: rule `stars_gaia` -> merged Gaia stars and the run's summary."""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821 - injected by Snakemake
import numpy as np  # noqa: E402
import pyarrow as pa  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402
from _common import end_job, setup_logging  # noqa: E402

from straylight.catalog.gaia import write_parquet  # noqa: E402
from straylight.util.io import write_json_atomic  # noqa: E402

log = setup_logging(snakemake)  # noqa: F821
tables = [pq.read_table(p) for p in snakemake.input.stars]  # noqa: F821
merged = pa.concat_tables(tables, promote_options="default") if tables else pa.table({})
cols = {k: merged[k].to_numpy() for k in merged.column_names}
n = merged.num_rows
dups = 0
if n:
    _, first = np.unique(cols["source_id"], return_index=True)
    keep = np.sort(first)
    dups = n - keep.size
    cols = {k: v[keep] for k, v in cols.items()}
write_parquet(cols, snakemake.output.stars, {"duplicates_across_files_dropped": dups})  # noqa: F821
summaries = [json.loads(Path(p).read_text()) for p in snakemake.input.summaries]  # noqa: F821
total = {
    "files": summaries,
    "stars": int(n - dups),
    "duplicates_across_files": int(dups),
    "quarantined": sum(s["quarantined"] for s in summaries),
}
write_json_atomic(total, snakemake.output.summary)  # noqa: F821
log.info(
    "%d files: %d stars, %d quarantined rows, %d duplicates across files",
    len(summaries),
    total["stars"],
    total["quarantined"],
    dups,
)
end_job()
