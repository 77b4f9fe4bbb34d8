"""The fidelity policy: how much error each fast path may add (models.tolerance split into
:data:`ERROR_BUDGET_SHARES`), which samples are evaluated (models.unobservable_samples), and
which earthshine model runs (models.earthshine.method).

The sources hold their fast paths (tables, skips on bounds); this object tells each what error
it may spend, so the shares are set, and add up, in one place."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from straylight.config import Campaign

# the tables' build per (node, door state) is given with the tables
from straylight.sources.earthshine.nodes import (
    LUT_BUILD_SECONDS_PER_NODE,
    MOONLIT_LUT_BUILD_SECONDS_PER_NODE,
)

__all__ = ["ERROR_BUDGET_SHARES", "LUT_SAVED_SECONDS_PER_SAMPLE", "unobservable_samples", "FidelityPolicy"]

#: Shares of models.tolerance (a fraction of the total) held by each fast path; they add up to 1.
#: The earthshine table must validate within its share; the moonlit Earth has two: the samples
#: skipped on its bound, and the coarse grid of the others (bench/run.py moonlit_grid measures
#: it); the skipped star pairs and the skipped Moon and planets are held to theirs by bounds.
ERROR_BUDGET_SHARES = {
    "earthshine_lut": 0.5,
    "moonlit_earthshine_skip": 0.125,
    "moonlit_earthshine_grid": 0.125,
    "stars_skip": 0.125,
    "moon_and_planets_skip": 0.125,
}

#: What the sunlit table saves per evaluated sample over the direct sum, seconds on one reference
#: core (``straylight plan`` prices a campaign on the direct sum with it; ``straylight plan
#: --calibrate`` times the direct sum against it; docs/performance.md gives the method).
LUT_SAVED_SECONDS_PER_SAMPLE = 0.08e-3


def unobservable_samples(campaign) -> str:
    """models.unobservable_samples of a campaign: 'evaluate' (every cube sample gets its
    background) or 'skip' (samples that break a constraint get NaN in every component).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its ``settings.models``).

    Returns
    -------
    str
        ``"evaluate"`` or ``"skip"``.
    """
    return campaign.settings.models.unobservable_samples


@dataclass
class FidelityPolicy:
    """One campaign's error budget and fast-path choices.  ``moonlit_skip_share``: the fraction
    of the tolerance the moonlit Earth's skipped samples may take (0: none skipped, as the
    benchmark's reference runs).

    Parameters
    ----------
    campaign : Campaign
        The campaign (its ``settings.models``: the tolerance, the samples evaluated).
    moonlit_skip_share : float
        Fraction of the tolerance the moonlit Earth's skipped samples may take, in [0, 1].
    """

    campaign: Campaign
    moonlit_skip_share: float = ERROR_BUDGET_SHARES["moonlit_earthshine_skip"]

    @cached_property
    def tolerance(self) -> float:
        """models.tolerance: the error allowed to the fast paths together, a fraction of the total."""
        return float(self.campaign.settings.models.tolerance)

    def share(self, name: str) -> float:
        """Fast path ``name``'s share of the tolerance (:data:`ERROR_BUDGET_SHARES`).

        Parameters
        ----------
        name : str
            A key of :data:`ERROR_BUDGET_SHARES`.

        Returns
        -------
        float
            The share, a fraction of the tolerance.
        """
        return ERROR_BUDGET_SHARES[name]

    def budget(self, share: str) -> float:
        """The error (a fraction of the total) fast path ``share`` of :data:`ERROR_BUDGET_SHARES`
        may add: its share times the tolerance.

        Parameters
        ----------
        share : str
            A key of :data:`ERROR_BUDGET_SHARES`.

        Returns
        -------
        float
            The error allowed, a fraction of the total background.
        """
        return ERROR_BUDGET_SHARES[share] * self.tolerance

    def accepts_table(self, share: str, validated_error: float) -> bool:
        """Whether a table whose validated error (a fraction of the total) is
        ``validated_error`` stays within ``share``'s budget.

        Parameters
        ----------
        share : str
            A key of :data:`ERROR_BUDGET_SHARES`.
        validated_error : float
            The table's largest error in its validation, a fraction of the total.

        Returns
        -------
        bool
            True when ``validated_error`` <= the share times the tolerance.
        """
        return validated_error <= ERROR_BUDGET_SHARES[share] * self.tolerance

    @property
    def unobservable_samples(self) -> str:
        """models.unobservable_samples: 'evaluate' or 'skip'."""
        return unobservable_samples(self.campaign)

    @staticmethod
    def tables_build_seconds(sunlit_node_states: int, moonlit_node_states: int) -> tuple[float, float]:
        """(both tables, the moonlit one): the table path's build on one core, s, at
        :data:`LUT_BUILD_SECONDS_PER_NODE` and :data:`MOONLIT_LUT_BUILD_SECONDS_PER_NODE`.

        Parameters
        ----------
        sunlit_node_states : int
            The sunlit table's (node, door state) pairs to build.
        moonlit_node_states : int
            The moonlit table's (node, door state) pairs to build.

        Returns
        -------
        total_s : float
            Both tables' build on one core, s.
        moonlit_s : float
            The moonlit table's part of it, s.
        """
        moonlit_s = MOONLIT_LUT_BUILD_SECONDS_PER_NODE * moonlit_node_states
        return LUT_BUILD_SECONDS_PER_NODE * sunlit_node_states + moonlit_s, moonlit_s

    @staticmethod
    def earthshine_method(requested: str) -> tuple[str, str]:
        """(method, reason): 'lut' or 'direct' for the sunlit Earth, from models.earthshine.method
        (``requested``: auto | lut | direct).  auto takes the table whatever the campaign's size:
        a sample then has the same value in a campaign of any size, in ``straylight sky`` and
        in the API, and the table's build is a one-time cost per model and machine that every
        later command and campaign reuses (``straylight plan`` and the build itself say when it
        is due, with its time).  The direct sum is the reference, on request.  Blind to the
        cache on purpose: the same config gives the same products on every machine.

        Parameters
        ----------
        requested : str
            models.earthshine.method: ``"auto"``, ``"lut"`` or ``"direct"``.

        Returns
        -------
        method : str
            ``"lut"`` or ``"direct"``.
        reason : str
            Why, for the models' record.
        """
        if requested == "direct":
            return "direct", "models.earthshine.method = direct"
        return "lut", f"models.earthshine.method = {requested}"
