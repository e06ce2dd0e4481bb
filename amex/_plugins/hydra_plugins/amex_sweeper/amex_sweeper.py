"""``hydra/sweeper=amex``: Hydra's basic sweeper plus grids, shards and longest-first order.

The jobs are those of :func:`amex.app.sweeps.sweep_jobs` (the params' and the command line's
product,
one product per grid of ``hydra.sweeper.grids``, every shard of a job with ``shards > 1``),
launched longest first (:func:`amex.app.sweeps.order_jobs`; ``hydra.sweeper.order=given`` keeps the
declaration order) in one batch, so a SLURM launcher submits the whole sweep as one job array.
Hydra imports this module when it looks for plugins (outside ``sys.modules``, hence no
``from __future__ import annotations``): it stays light and imports amex lazily.
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.config_store import ConfigStore
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


class AmexSweeper(BasicSweeper):
    """See the module notes."""

    def __init__(
        self,
        max_batch_size: Optional[int] = None,  # noqa: UP045 - evaluated by dataclasses
        params: Optional[dict[str, str]] = None,  # noqa: UP045
        grids: Optional[dict[str, dict[str, str]]] = None,  # noqa: UP045
        order: str = "longest_first",
    ) -> None:
        super().__init__(max_batch_size=max_batch_size, params=params)
        self.grids = grids
        if order not in ORDERS:
            raise ValueError(f"invalid hydra.sweeper.order={order!r}; valid: {', '.join(ORDERS)}")
        self.order = order

    def sweep(self, arguments: list[str]) -> Any:
        """Launch every job (module notes); return the launcher's results per batch."""
        from amex.app.sweeps import job_defaults, order_jobs, sweep_jobs

        assert self.config is not None and self.launcher is not None
        params: Any = OmegaConf.to_container(OmegaConf.create(self.params or {}))
        grids: Any = OmegaConf.to_container(OmegaConf.create(self.grids)) if self.grids else None
        jobs = sweep_jobs(params, grids, arguments, int(self.config.get("shards") or 1))
        if self.order == "longest_first":
            jobs = order_jobs(jobs, job_defaults(self.config))
        self.overrides = list(self.split_overrides_to_chunks(jobs, self.max_batch_size))
        sweep_dir = Path(self.config.hydra.sweep.dir)
        sweep_dir.mkdir(parents=True, exist_ok=True)
        OmegaConf.save(self.config, sweep_dir / "multirun.yaml")
        returns = []
        index = 0
        while not self.is_done():  # the jobs were checked by amex-run before Hydra started
            batch = self.get_job_batch()
            results = self.launcher.launch(batch, initial_job_idx=index)
            for r in results:
                _ = r.return_value  # re-raises a job's failure
            index += len(batch)
            returns.append(results)
        return returns
