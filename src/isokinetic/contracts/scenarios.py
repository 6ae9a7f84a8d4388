"""Names and size of the blind suite's scenarios: the one place the workflow and isokinetic.stages.blind_*
read them from. Imports nothing heavy, so that building the workflow's DAG stays fast."""

from __future__ import annotations

#: Effect names of the diagnosis contract, in their canonical order (verdict/truth text order).
EFFECTS = ("friction", "leakage", "asymmetry", "discharge", "viscosity", "air")
#: The diagnosis' catalogue, in canonical order: the suite's EFFECTS and effects the suite does not draw yet
#: (path_asymmetry: a one-sided resistance of the whole flow path, issue 21).
CATALOGUE = ("friction", "leakage", "asymmetry", "path_asymmetry", "discharge", "viscosity", "air")
#: Out-of-catalogue effects of the suite (isokinetic.stages.blind_generate.out_of_catalogue_true_effects).
OUT_OF_CATALOGUE = ("stribeck", "backlash", "relief")
SCENARIO_PREFIX = "blind-"


def suite_size(n_per_effect: int, n_pairs: int, n_none: int, n_out: int = 0) -> int:
    """Scenarios of a suite: each effect n_per_effect times alone, the pairs, the none, the out-of-catalogue."""
    return len(EFFECTS) * n_per_effect + n_pairs + n_none + n_out


def scenario_names(n: int) -> list[str]:
    """blind-000, blind-001, ... (n names)."""
    return [f"{SCENARIO_PREFIX}{k:03d}" for k in range(n)]
