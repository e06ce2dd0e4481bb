"""amex from Python, without the command line: compose, run a few episodes, read the rows.

Run from any directory: ``python examples/python_api.py [OUT_DIR]`` (default: ./api_example).
"""

import sys
from pathlib import Path

import amex

out = Path(sys.argv[1] if len(sys.argv) > 1 else "api_example")

# The same configuration `amex-run task=3 method=amex episodes=4 max_time=2` would run.
config = amex.compose(task=3, method="amex", episodes=4, max_time=2.0)

# Two environments, their MCAP logs beside them (open them with `amex-log info|plot|view`).
rows = amex.run_episodes(config, envs=range(2), log_dir=out / "logs")
print(rows[["task", "method", "env", "success", "final_distance", "final_time", "log"]])

# The whole run, as amex-run writes it (episodes.csv, summary.json; running it again resumes),
# and the same environments with DMP: rows of one env are paired across methods.
amex.run(config, out / "amex")
amex.run(amex.compose(task=3, method="dmp", episodes=4, max_time=2.0), out / "dmp")
table = amex.read_runs(out).pivot_table(index="env", columns="method", values="final_distance")
print(table)
