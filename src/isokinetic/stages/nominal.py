"""Runner of the nominal model windows (paper Sec. 4.5, Fig. 13-14) of one campaign folder.

Reads the campaign's damper, cases and measured windows and runs the noise-free model through the
campaign's own plan with the measured drive (:mod:`isokinetic.measurement.model_windows`,
:mod:`isokinetic.measurement.drive`).
"""

from __future__ import annotations

import logging

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign import viscosity_scales
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.measurement.drive import case_drives
from isokinetic.measurement.model_windows import model_windows, plan_time_ends
from isokinetic.measurement.windows import WindowSpec
from isokinetic.physics.damper import NOMINAL

log = logging.getLogger("isokinetic.nominal")


def nominal_stage(campaign_root, spec: WindowSpec) -> pd.DataFrame:
    """Nominal-model windows of a validated campaign folder ``results/<campaign>/``.

    Reads ``ingest/campaign.json`` (damper block) and ``cases.parquet``; without a damper block
    returns an empty WINDOWS table and logs why. With a viscosity law (format 1.1) and case temperatures,
    each case runs at its own temperature's viscosity. Cases with NaN ``duration_s`` take the last time
    stamp of their measured series as the record length.
    """
    folder = CampaignFolder.at(campaign_root)
    meta = folder.meta
    campaign, damper = meta.campaign, meta.damper
    if damper is None:
        log.info("campaign %s: no damper block in campaign.json; no nominal model windows", campaign)
        return tables.empty(tables.WINDOWS)
    cases = folder.validated_cases()
    drives = case_drives(cases, folder.table("windows", "windows"))
    durations = plan_time_ends(cases, lambda row: folder.timeseries(row, ["time_s"])["time_s"].to_numpy())
    scales = viscosity_scales(meta, cases)
    if scales:
        log.info("campaign %s: nominal viscosity at each case's temperature (viscosity law): %.4g..%.4g Pa s",
                 campaign, damper.viscosity_Pa_s * min(scales.values()), damper.viscosity_Pa_s * max(scales.values()))
    out = model_windows(campaign, cases, damper, NOMINAL, spec, durations, drives=drives, viscosity_scales=scales)
    log.info("campaign %s: %d nominal model windows from %d triangle case(s)", campaign, len(out),
             out["case"].nunique() if len(out) else 0)
    return out
