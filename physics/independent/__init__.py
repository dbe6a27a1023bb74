"""A second, independent gear-pair truth generator (``docs/independent-simulator.md``).

One line-of-action degree of freedom excited by the loaded static transmission error of
per-pair stiffnesses, solved in the frequency domain, through a modal transfer path — a model
that differs in kind from :mod:`physics.simulator` (six-DOF, elemental contact lines, Newmark).

API
---
- :func:`generate_record` ``(model, seed) -> IndependentRecord`` (``channels``, ``sample_rate_hz``,
  ``truth``; ``.record_data()`` and ``.campaign()`` give gearwatch's ingest objects)
- :func:`random_model` ``(seed, *, contact_ratio=None, pinion_teeth=None, gear_teeth=None,
  noise_to_signal=None, speed_drift_fraction=None, sensor_angle_deg=None, tachometer=True,
  seconds=12.0, sample_rate_hz=20000.0, dynamics=None) -> IndependentModel``
- ``IndependentModel.dynamics``: ``"linear"`` (LTI frequency-domain solve, default) or
  ``"nonlinear"`` (time-stepped, per-sample stiffness, dynamic contact loss; numba)
- :func:`random_campaign` ``(seed, *, days=8, spalled=True, onset_day=None, tachometer=True,
  seconds=12.0, **rig) -> list[CampaignDay]`` (issue 10's randomised campaign conditions)
- :func:`campaign_days` ``(base, days=8, *, onset_day=5, spall=None, depths_um=(4, 8, 15, 25),
  extents=None, load_jitter=0, speed_jitter=0, gain_step_day=None, gain_step_factor=2,
  glitch_days=(), glitches_per_day=1, seed=0) -> list[CampaignDay]``
- :func:`generate_campaign` ``(plan) -> Iterator[IndependentRecord]``
- :func:`write_campaign` ``(out_dir, plan, *, campaign_id, record_format="wav", start, description)
  -> Path`` (campaign.toml via ``ingest.manifest.dump_manifest`` + records + truth.json)
- parameters: :class:`IndependentModel` and its parts (:class:`PairGeometry`,
  :class:`PairStiffness`, :class:`ToothErrors`, :class:`Spall`, :class:`Crack`, :class:`Mode`,
  :class:`TransferPath`, :class:`Operating`, :class:`Tachometer`, :class:`Acquisition`,
  :class:`Artefacts`); :func:`model_to_dict` / :func:`model_from_dict`.
"""

from physics.independent.campaign import (
    CampaignDay,
    campaign_days,
    generate_campaign,
    write_campaign,
)
from physics.independent.generator import (
    IndependentRecord,
    campaign_for,
    generate_record,
    pair_derived,
)
from physics.independent.model import (
    Acquisition,
    Artefacts,
    Crack,
    IndependentModel,
    IndependentModelError,
    Mode,
    Operating,
    PairGeometry,
    PairStiffness,
    Spall,
    Tachometer,
    ToothErrors,
    TransferPath,
    model_from_dict,
    model_to_dict,
    validate_model,
)
from physics.independent.scenarios import random_campaign, random_model

__all__ = [
    "Acquisition",
    "Artefacts",
    "CampaignDay",
    "Crack",
    "IndependentModel",
    "IndependentModelError",
    "IndependentRecord",
    "Mode",
    "Operating",
    "PairGeometry",
    "PairStiffness",
    "Spall",
    "Tachometer",
    "ToothErrors",
    "TransferPath",
    "campaign_days",
    "campaign_for",
    "generate_campaign",
    "generate_record",
    "model_from_dict",
    "model_to_dict",
    "pair_derived",
    "random_campaign",
    "random_model",
    "validate_model",
    "write_campaign",
]
