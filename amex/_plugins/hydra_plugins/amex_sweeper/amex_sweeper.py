"""``hydra/sweeper=amex``: the jobs of :func:`amex.app.sweeps.sweep_jobs`, longest first, one batch.

The jobs are the params' and the command line's product, one product per grid of
``hydra.sweeper.grids``, every shard of a job with ``shards > 1``; they are launched longest first
(:func:`amex.app.sweeps.order_jobs`; ``hydra.sweeper.order=given`` keeps the declaration order)
in one batch unless ``max_batch_size`` says otherwise, so a SLURM launcher submits the whole sweep
as one job array. Built on Hydra's public plugin API (``hydra.plugins.sweeper.Sweeper``). Hydra
imports this module when it looks for plugins (outside ``sys.modules``, hence no
``from __future__ import annotations``): it stays light and imports amex lazily.
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from hydra.core.plugins import Plugins
from hydra.plugins.sweeper import Sweeper
from omegaconf import OmegaConf

ORDERS = ("longest_first", "given")


@dataclass
class AmexSweeperConf:
    """``hydra.sweeper.*`` of ``hydra/sweeper=amex``."""

    _target_: str = "hydra_plugins.amex_sweeper.amex_sweeper.AmexSweeper"
    max_batch_size: Any = None  # jobs per launch; None: the whole sweep at once (one array)
    params: Any = None  # key -> values, as Hydra's basic sweeper
    grids: Any = None  # name -> {key: values}: the union of one product per grid
    order: str = "longest_first"  # or "given"


ConfigStore.instance().store(group="hydra/sweeper", name="amex", node=AmexSweeperConf)


class AmexSweeper(Sweeper):
    """See the module notes."""

    def __init__(
        self,
        max_batch_size: Optional[int] = None,  # noqa: UP045 - evaluated by dataclasses
        params: Optional[dict[str, str]] = None,  # noqa: UP045
        grids: Optional[dict[str, dict[str, str]]] = None,  # noqa: UP045
        order: str = "longest_first",
    ) -> None:
        if order not in ORDERS:
            raise ValueError(f"invalid hydra.sweeper.order={order!r}; valid: {', '.join(ORDERS)}")
        if max_batch_size is not None and max_batch_size < 1:
            raise ValueError(f"invalid hydra.sweeper.max_batch_size={max_batch_size}; valid: >= 1")
        self.max_batch_size = max_batch_size
        self.params = params
        self.grids = grids
        self.order = order
        self.config: Any = None
        self.launcher: Any = None
        self.hydra_context: Any = None

    def setup(self, *, hydra_context: Any, task_function: Any, config: Any) -> None:
        """Keep the context and build the configured launcher (Hydra's plugin registry)."""
        self.hydra_context = hydra_context
        self.config = config
        self.launcher = Plugins.instance().instantiate_launcher(
            hydra_context=hydra_context, task_function=task_function, config=config
        )

    def sweep(self, arguments: list[str]) -> Any:
        """Launch every job (module notes); return the launcher's results per batch."""
        from amex.app.sweeps import job_defaults, order_jobs, sweep_jobs

        params: Any = OmegaConf.to_container(OmegaConf.create(self.params or {}))
        grids: Any = OmegaConf.to_container(OmegaConf.create(self.grids)) if self.grids else None
        shards = int(self.config.get("shards") or 1)
        loader = self.hydra_context.config_loader
        jobs = sweep_jobs(params, grids, arguments, shards, config_loader=loader)
        if self.order == "longest_first":
            jobs = order_jobs(jobs, job_defaults(self.config))
        size = self.max_batch_size or max(len(jobs), 1)
        batches = [jobs[i : i + size] for i in range(0, len(jobs), size)]
        sweep_dir = Path(self.config.hydra.sweep.dir)
        sweep_dir.mkdir(parents=True, exist_ok=True)
        OmegaConf.save(self.config, sweep_dir / "multirun.yaml")
        returns = []
        index = 0
        for batch in batches:  # the jobs were checked by amex-run before Hydra started
            results = self.launcher.launch(batch, initial_job_idx=index)
            for r in results:
                _ = r.return_value  # re-raises a job's failure
            index += len(batch)
            returns.append(results)
        return returns
