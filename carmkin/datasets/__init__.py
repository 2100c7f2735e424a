"""Synthetic X-ray datasets from poses a real C-arm can take (issue 28; the ``datasets`` extra).

:func:`sample_poses` draws feasible poses from a prior (:mod:`.priors`) as :class:`~.samples.PoseSamples`;
:mod:`.render` renders them in batches through nanodrr with landmark labels; :mod:`.shards` writes Parquet
shards (one row per image) deterministically and resumably; :mod:`.scale` runs shards on Ray; :mod:`.contents`
reads a dataset back. Library units: m and rad, table frame 0.
"""

from __future__ import annotations

from .priors import CLINICAL_SD_DEG, PRIORS
from .samples import DEFAULT_MARGIN, PoseSamples, Rejections
from .shards import Spec

__all__ = ["CLINICAL_SD_DEG", "DEFAULT_MARGIN", "PRIORS", "PoseSamples", "Rejections", "Spec", "generate", "info",
           "sample_poses"]


def sample_poses(system, prior, n, seed=0, patient=None, *, shard=0, margin=DEFAULT_MARGIN, **prior_parameters):
    """``n`` feasible poses of ``system`` drawn from ``prior`` (one of :data:`PRIORS`) around ``patient`` (a
    patient model or a list of :class:`~carmkin.robot.collision.Obstacle`, or None) with the random stream of
    ``(seed, shard)``: every sample has its joints in range and an exact clearance ≥ ``margin`` (m) to table,
    floor and patient (checked after drawing). ``prior_parameters``: the prior's own (see
    :mod:`carmkin.datasets.priors`). Returns :class:`PoseSamples` with provenance and the rejection report; a
    prior that cannot be met raises :class:`~carmkin.errors.DatasetError` saying why."""
    import numpy as np

    from carmkin import _version
    from carmkin.errors import DatasetError
    from carmkin.robot.validity import require_system
    from carmkin.validation import integer, real_scalar

    from . import priors, samples

    require_system(system, DatasetError)
    prior = priors.check_prior(prior)
    from .scale import MAX_IMAGES

    n = integer(n, "n", low=1, high=MAX_IMAGES, error=DatasetError)
    seed = integer(seed, "seed", low=0, error=DatasetError)
    shard = integer(shard, "shard", low=0, error=DatasetError)
    margin = real_scalar(margin, "margin", error=DatasetError, low=0.0, high=1.0, unit="m")
    rng = np.random.default_rng([seed, shard])
    priors.check_parameters(prior, prior_parameters)
    # the sweep prior names its sweeps by the shard too: labels unique across the shards of a dataset
    where = (shard,) if prior == "sweep" else ()
    Q, labels, nominal, rejections, params = priors.DRAW[prior](system, patient, rng, n, margin, *where,
                                                               **prior_parameters)
    provenance = {"preset": system.name, "patient": samples.describe_patient(patient), "prior": prior,
                  "parameters": params, "seed": seed, "shard": shard, "margin_m": margin, "carmkin": _version()}
    return samples.build(system, patient, Q, labels, nominal, provenance, rejections, margin)


def generate(spec, out, **options):
    """Make the dataset of a :class:`~.shards.Spec` in the folder ``out`` (:func:`carmkin.datasets.scale.generate`)."""
    from .scale import generate as run

    return run(spec, out, **options)


def info(out):
    """What the dataset folder ``out`` holds (:func:`carmkin.datasets.contents.info`)."""
    from .contents import info as read

    return read(out)
