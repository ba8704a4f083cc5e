"""Settings of the ``acvt`` strategy (README "Strategy acvt"), validated, and the dropout,
relocation and cell settings they give on a domain (:mod:`.dropout`, :mod:`.relocation`,
:mod:`.cells`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coverage_ros.core.strategies.acvt.cells import CellSpec
from coverage_ros.core.strategies.acvt.dropout import (
    DEFAULT_FILTER_GAIN,
    PAPER_EPSILON,
    STALL_ITERATIONS,
    DropoutConfig,
)
from coverage_ros.core.strategies.acvt.relocation import RelocationConfig
from coverage_ros.errors import ConfigError


@dataclass(frozen=True)
class AcvtParams:
    """Settings of the ``acvt`` strategy (see README "Strategy acvt")."""

    dropout: bool = True  # agent dropout and reinsertion (False: iCVT + projection)
    epsilon: float = PAPER_EPSILON  # threshold on the filtered Delta I (Eq. 10)
    filter_gain: float = DEFAULT_FILTER_GAIN  # low-pass gain of Delta I, in (0, 1]
    drop_factor: float | None = None  # tau_drop = drop_factor * mean M; None: k / (k - 1)
    #: the dropout also ends after this many iterations without a new lowest I (0: never);
    #: "auto": STALL_ITERATIONS where the density's support has separate targets, else never
    stall_iterations: int | str = "auto"
    visibility: bool = False  # Eq. 11-12: only the part of the cell in line of sight
    scale_x: float = 1.0  # a of T_c in Eq. 15 (shape constraint), on map x
    scale_y: float = 1.0  # b of T_c in Eq. 15, on map y
    gap_penalty: float = 0.0  # lambda of Eq. 15 [m per m of rho = 0 crossed]
    speed_weighted: bool = True  # Eq. 16-18 when the robots' speeds differ
    #: a light robot of a settled team relocates (.relocation); "auto": when the density's
    #: support is split into separate targets (on one connected area a CVT's split has no
    #: wrong target to mend, and a relocation trades the coverage cost H for mass balance)
    relocate: bool | str = "auto"

    def __post_init__(self) -> None:
        if not (self.relocate == "auto" or isinstance(self.relocate, bool | np.bool_)):
            raise ConfigError.at("relocate", "must be true, false or auto", self.relocate)
        if not (self.stall_iterations == "auto" or (
                isinstance(self.stall_iterations, int | np.integer)
                and not isinstance(self.stall_iterations, bool) and self.stall_iterations >= 0)):
            raise ConfigError.at("stall_iterations", "must be an integer >= 0 or auto",
                                 self.stall_iterations)
        for name in ("dropout", "visibility", "speed_weighted"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                raise ConfigError.at(name, "must be true or false", getattr(self, name))
        for name in ("epsilon", "filter_gain", "drop_factor", "scale_x", "scale_y",
                     "gap_penalty"):
            value = getattr(self, name)
            if value is None and name == "drop_factor":
                continue
            if isinstance(value, bool) or not isinstance(value, int | float | np.number):
                raise ConfigError.at(name, "must be a number", value)
        # The cell and dropout settings validate their own ranges.
        self.dropout_config()
        self.cell_spec()

    def dropout_config(self, targets: int = 1) -> DropoutConfig:
        """The dropout on a domain whose density has ``targets`` separate parts (for
        ``stall_iterations: auto``)."""
        stall = self.stall_iterations
        if stall == "auto":
            stall = STALL_ITERATIONS if targets > 1 else 0
        return DropoutConfig(bool(self.dropout), float(self.epsilon), float(self.filter_gain),
                             None if self.drop_factor is None else float(self.drop_factor),
                             int(stall))

    def relocation_config(self, targets: int = 1) -> RelocationConfig:
        """The relocation on a domain whose density has ``targets`` separate parts (for
        ``relocate: auto``). Part of alpha-CVT: iCVT + projection (dropout off, the paper's
        baseline) never relocates. A robot relocates at most twice: its prediction is from a
        settled team, and a live team may settle elsewhere than predicted."""
        wanted = targets > 1 if self.relocate == "auto" else bool(self.relocate)
        return RelocationConfig(enabled=bool(wanted and self.dropout), max_moves=2)

    def cell_spec(self) -> CellSpec:
        return CellSpec(bool(self.visibility), (float(self.scale_x), float(self.scale_y)),
                        float(self.gap_penalty))
