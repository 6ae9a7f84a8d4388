"""Names, composition and chunks of the blind suite's scenarios: the one place the workflow and
isokinetic.stages.blind_* read them from. Imports only numpy (which Snakemake has loaded already) and the effect
registry (which imports nothing), so that building the workflow's DAG stays fast."""

from __future__ import annotations

import itertools

import numpy as np

from isokinetic.physics import effects as registry

#: Effects the suite draws (those of the registry with a blind-suite draw), in their canonical order
#: (verdict/truth text order).
EFFECTS = registry.BLIND_EFFECTS
#: The diagnosis' catalogue (the registry's fitted effects), in canonical order: the suite's EFFECTS and effects
#: the suite does not draw yet (path_asymmetry: a one-sided resistance of the whole flow path, issue 21).
CATALOGUE = registry.CATALOGUE
#: Out-of-catalogue effects of the suite that hide from the steady characteristic (issue 35), each with the
#: ``where`` axis it shows on (isokinetic.blind.hidden): a groove open near mid-stroke, a bore worn there,
#: a rod's gas spring; an orifice wearing and the oil warming (unlogged) over the campaign.
HIDDEN_AXES = {"bypass": "position", "worn_bore": "position", "gas_spring": "position", "wear": "time",
               "warmup": "time"}
#: Out-of-catalogue effects of the suite (isokinetic.blind.generate.out_of_catalogue_true_effects), in
#: the order ``n_out`` cycles through them: the steady characteristic's (Stribeck friction, backlash, a relief
#: valve) and the hidden ones (HIDDEN_AXES) interleaved, so that a small suite holds both.
OUT_OF_CATALOGUE = ("stribeck", "bypass", "backlash", "wear", "relief", "worn_bore", "warmup", "gas_spring")
#: Truths of the sine-only scenarios, in turn: none, then each catalogue effect alone.
SINE_TRUTHS: tuple[tuple[str, ...], ...] = ((),) + tuple((e,) for e in EFFECTS)
SCENARIO_PREFIX = "blind-"
#: Range of the magnitudes drawn, in detection levels.
MULTIPLE_RANGE = (1.0, 5.0)
#: One detection level: an effect's noise-free change of the observations at this rms_z (in standard errors).
DETECTION_RMS_Z = 3.0

#: Expected CPU-seconds of one scenario's diagnosis, by kind: the means of benchmark/blind_suite.py (seed 777, 74
#: scenarios with the sensor chain; a sine-only one's median is 7 s, its range 1-23 s; a force-channel low-pass
#: doubles a scenario's cost, which the kinds cannot see); what :func:`balanced_chunks` balances. Generation adds
#: about 0.5 s to each.
EXPECTED_COST_S = {"none": 1.6, "single": 2.2, "pair": 2.5, "out": 4.0, "sine": 8.0}

#: One scenario of the composition: (truth, multiples, out-of-catalogue kind, waveform).
Kind = tuple[tuple[str, ...], dict[str, float], str, str]


def suite_size(n_per_effect: int, n_pairs: int, n_none: int, n_out: int = 0, n_sine: int = 0) -> int:
    """Scenarios of a suite: each effect n_per_effect times alone, the pairs, the none, the out-of-catalogue,
    the sine-only."""
    return len(EFFECTS) * n_per_effect + n_pairs + n_none + n_out + n_sine


def scenario_names(n: int) -> list[str]:
    """blind-000, blind-001, ... (n names)."""
    return [f"{SCENARIO_PREFIX}{k:03d}" for k in range(n)]


def suite_composition(seed: int, n_per_effect: int, n_pairs: int, n_none: int, n_out: int = 0,
                      n_sine: int = 0) -> list[Kind]:
    """(truth, multiples, out-of-catalogue kind, waveform) per scenario, in name order.

    Singles of one effect get stratified multiples (k-th of n in [1 + 4k/n, 1 + 4(k+1)/n], strata
    in random order); pairs are distinct effect pairs (cycled when more than 15 are asked) with
    U[1, 5] multiples; ``n_out`` out-of-catalogue scenarios cycle through OUT_OF_CATALOGUE; these triangle
    campaigns are shuffled so a name does not tell its kind. The ``n_sine`` sine-only campaigns (their
    manifests say sine anyway) follow them, cycling through SINE_TRUTHS (none, then each effect alone at
    U[1, 5]) and shuffled among themselves, from a stream of their own: the triangle scenarios are the same
    with or without them.
    """
    for key, v in (("n_per_effect", n_per_effect), ("n_pairs", n_pairs), ("n_none", n_none), ("n_out", n_out),
                   ("n_sine", n_sine)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ValueError(f"{key}: must be a non-negative integer, got {v!r}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5EED]))
    lo, hi = MULTIPLE_RANGE
    kinds: list[Kind] = []
    for e in EFFECTS:
        strata = rng.permutation(n_per_effect)
        for k in strata:
            u = rng.uniform(k / n_per_effect, (k + 1) / n_per_effect)
            kinds.append(((e,), {e: lo + (hi - lo) * float(u)}, "", "triangle"))
    all_pairs = list(itertools.combinations(EFFECTS, 2))
    order = rng.permutation(len(all_pairs))
    for i in range(n_pairs):
        pair = all_pairs[int(order[i % len(all_pairs)])]
        kinds.append((pair, {e: float(rng.uniform(lo, hi)) for e in pair}, "", "triangle"))
    kinds += [((), {}, "", "triangle") for _ in range(n_none)]
    kinds += [((), {}, OUT_OF_CATALOGUE[i % len(OUT_OF_CATALOGUE)], "triangle") for i in range(n_out)]
    out = [kinds[int(i)] for i in rng.permutation(len(kinds))]
    sine_rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5EED, 0x51E]))
    sines = [(truth, {e: float(sine_rng.uniform(lo, hi)) for e in truth}, "", "sine")
             for truth in (SINE_TRUTHS[i % len(SINE_TRUTHS)] for i in range(n_sine))]
    return out + [sines[int(i)] for i in sine_rng.permutation(n_sine)]


def kind_name(kind: Kind) -> str:
    """'sine', 'out', 'pair', 'single' or 'none': the key of EXPECTED_COST_S."""
    truth, _mult, out, waveform = kind
    if waveform == "sine":
        return "sine"
    if out:
        return "out"
    return {0: "none", 1: "single"}.get(len(truth), "pair")


def balanced_chunks(kinds: list[Kind], n_chunks: int) -> list[list[int]]:
    """Scenario indices per chunk, balanced by expected cost (EXPECTED_COST_S): longest first, each to the
    chunk with the least so far (ties: the lower chunk); each chunk's indices in name order."""
    load = [0.0] * n_chunks
    chunks: list[list[int]] = [[] for _ in range(n_chunks)]
    costs = [EXPECTED_COST_S[kind_name(k)] for k in kinds]
    for i in sorted(range(len(kinds)), key=lambda i: (-costs[i], i)):
        c = min(range(n_chunks), key=lambda c: (load[c], c))
        load[c] += costs[i]
        chunks[c].append(i)
    return [sorted(c) for c in chunks]
