"""Registering one bag pair with the shared pipeline, in this process or in a worker.

Without warm start every pair is independent: each goes through a fresh
``RegistrationPipeline``, so the result of a pair never depends on which worker computed it or
what it computed before, and ``--jobs N`` gives the same results as ``--jobs 1``. With warm
start (one process only) a single pipeline carries the previous estimate from pair to pair,
exactly like the live node.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from frisicp_ros.bag.pairs import BagPair
from frisicp_ros.stream.pipeline import PairOutcome, PipelineSettings, RegistrationPipeline


@dataclass
class PairRegistrar:
    settings: PipelineSettings
    _pipeline: RegistrationPipeline | None = field(default=None, repr=False)

    def __call__(self, pair: BagPair) -> PairOutcome:
        if self.settings.warm_start:
            if self._pipeline is None:
                self._pipeline = RegistrationPipeline(self.settings)
            pipeline = self._pipeline
        else:
            pipeline = RegistrationPipeline(self.settings)
        outcome = pipeline.process(pair.model.cloud, pair.data.cloud)
        # The caller has the clouds; sending the converted points back would only cost pickling.
        return replace(outcome, data_msg=None, data_points=None, model_points=None)

    def __getstate__(self) -> dict[str, object]:
        if self.settings.warm_start:
            raise TypeError("a warm-started registrar carries state from pair to pair: one process only")
        return {"settings": self.settings, "_pipeline": None}
