"""The fidelity policy: how much error each fast path may add (models.tolerance split into
:data:`ERROR_BUDGET_SHARES`), which samples are evaluated (models.unobservable_samples), and
whether the sunlit earthshine table pays off (models.earthshine.method = auto).

The sources hold their fast paths (tables, skips on bounds); this object tells each what error
it may spend, so the shares are set, and add up, in one place."""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from straylight.config import Campaign
# the tables' build per (node, door state) is given with the tables
from straylight.sources.earthshine_lut import LUT_BUILD_SECONDS_PER_NODE, MOONLIT_LUT_BUILD_SECONDS_PER_NODE

#: Shares of models.tolerance (a fraction of the total) held by each fast path; they add up to 1.
#: The earthshine table must validate within its share; the moonlit Earth has two: the samples
#: skipped on its bound, and the coarse grid of the others (bench/run.py moonlit_grid measures
#: it); the skipped star pairs and the skipped Moon and planets are held to theirs by bounds.
ERROR_BUDGET_SHARES = {"earthshine_lut": 0.5, "moonlit_earthshine_skip": 0.125, "moonlit_earthshine_grid": 0.125,
                       "stars_skip": 0.125, "moon_and_planets_skip": 0.125}

#: models.earthshine.method = auto weighs reading the cached tables (a build is a one-time cost
#: per model and machine, which every later command and campaign reuses) against what the table
#: saves per evaluated sample over the direct sum, both in seconds on one core; their ratio is
#: the fewest samples for which auto takes the table (bench/earthshine_tables.py measures both).
LUT_LOAD_SECONDS = 1.0
LUT_SAVED_SECONDS_PER_SAMPLE = 0.08e-3
AUTO_TABLE_MIN_SAMPLES = int(round(LUT_LOAD_SECONDS / LUT_SAVED_SECONDS_PER_SAMPLE))


def unobservable_samples(campaign) -> str:
    """models.unobservable_samples of a campaign: 'evaluate' (every cube sample gets its
    background) or 'skip' (samples that break a constraint get NaN in every component)."""
    return str(campaign.config["models"].get("unobservable_samples", "evaluate"))


@dataclass
class FidelityPolicy:
    """One campaign's error budget and fast-path choices.  ``expected_samples``: how many
    (time, pointing) samples the model will evaluate (the cube: the whole campaign; a pointing
    table: its rows; one pointing: 1), which decides whether the sunlit table pays off;
    ``moonlit_skip_share``: the fraction of the tolerance the moonlit Earth's skipped samples
    may take (0: none skipped, as the benchmark's reference runs)."""

    campaign: Campaign
    expected_samples: int = 1
    moonlit_skip_share: float = ERROR_BUDGET_SHARES["moonlit_earthshine_skip"]

    @cached_property
    def tolerance(self) -> float:
        """models.tolerance: the error allowed to the fast paths together, a fraction of the total."""
        return float(self.campaign.config["models"].get("tolerance", 0.01))

    def share(self, name: str) -> float:
        """Fast path ``name``'s share of the tolerance (:data:`ERROR_BUDGET_SHARES`)."""
        return ERROR_BUDGET_SHARES[name]

    def budget(self, share: str) -> float:
        """The error (a fraction of the total) fast path ``share`` of :data:`ERROR_BUDGET_SHARES`
        may add: its share times the tolerance."""
        return ERROR_BUDGET_SHARES[share] * self.tolerance

    def accepts_table(self, share: str, validated_error: float) -> bool:
        """Whether a table whose validated error (a fraction of the total) is
        ``validated_error`` stays within ``share``'s budget."""
        return validated_error <= ERROR_BUDGET_SHARES[share] * self.tolerance

    @property
    def unobservable_samples(self) -> str:
        """models.unobservable_samples: 'evaluate' or 'skip'."""
        return unobservable_samples(self.campaign)

    @staticmethod
    def tables_build_seconds(sunlit_node_states: int, moonlit_node_states: int) -> tuple[float, float]:
        """(both tables, the moonlit one): the table path's build on one core, s, at
        :data:`LUT_BUILD_SECONDS_PER_NODE` and :data:`MOONLIT_LUT_BUILD_SECONDS_PER_NODE`."""
        moonlit_s = MOONLIT_LUT_BUILD_SECONDS_PER_NODE * moonlit_node_states
        return LUT_BUILD_SECONDS_PER_NODE * sunlit_node_states + moonlit_s, moonlit_s

    def earthshine_method(self, requested: str) -> tuple[str, str]:
        """(method, reason): 'lut' or 'direct' for the sunlit Earth, from models.earthshine.method
        (``requested``: auto | lut | direct) and, for auto, :attr:`expected_samples` against
        :data:`AUTO_TABLE_MIN_SAMPLES` (below it the direct sum is done before the cached tables
        are read).  Blind to the cache on purpose: the same config and samples give the same
        products on every machine, whether or not a table was built there before; a table that
        is not cached yet is built once (``straylight plan`` says so, with its time)."""
        if requested == "direct":
            return "direct", "models.earthshine.method = direct"
        if requested == "auto" and self.expected_samples < AUTO_TABLE_MIN_SAMPLES:
            return "direct", (f"auto: {self.expected_samples} samples, fewer than the {AUTO_TABLE_MIN_SAMPLES} "
                              f"that repay reading the tables")
        return "lut", f"{requested}: {self.expected_samples} samples"
