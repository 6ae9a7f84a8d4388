# Blind test of the diagnosis on withheld effects: one generation job, the diagnosis in a fixed
# number of chunks (each job starts Python once and diagnoses its share of the scenarios), one
# scoring job. Only blind_score reads the truth.

BLIND = config.get("blind") or {}
BLIND_NAMES = blind_scenario_names(BLIND)
BLIND_CHUNKS = max(1, min(int(BLIND.get("chunks", 2)), len(BLIND_NAMES)))
if BLIND and "blind" in CAMPAIGNS:
    raise WorkflowError("a campaign named 'blind' would share results/blind/ with the blind test; rename it")


def blind_chunk(wildcards):
    """The scenarios of chunk k: a fixed partition of the names (every k-th)."""
    return BLIND_NAMES[int(wildcards.chunk)::BLIND_CHUNKS]


rule blind_generate:
    """Blind scenarios: raw campaigns without their truth, and the truth kept apart for scoring."""
    output:
        raw=directory("results/blind/raw"),
        truth=directory("results/blind/truth"),
    log:
        "logs/blind/generate.log",
    params:
        seed=BLIND.get("seed", 0),
        n_per_effect=BLIND.get("n_per_effect", 0),
        n_pairs=BLIND.get("n_pairs", 0),
        n_none=BLIND.get("n_none", 0),
        n_out=BLIND.get("n_out_of_catalogue", 0),
        names=BLIND_NAMES,
        start_fraction=config["windows"]["start_fraction"],
        end_fraction=config["windows"]["end_fraction"],
    script:
        "../scripts/blind_generate.py"


rule blind_diagnose:
    """The per-campaign chain (ingest to diagnosis) of one chunk of blind scenarios, truth unseen."""
    input:
        "results/blind/raw",
    output:
        directory("results/blind/diagnosis/chunk{chunk}"),
    log:
        "logs/blind/diagnose-chunk{chunk}.log",
    wildcard_constraints:
        chunk=r"\d+",
    params:
        names=blind_chunk,
        start_fraction=config["windows"]["start_fraction"],
        end_fraction=config["windows"]["end_fraction"],
        repeatability_tolerance=config["repeatability"]["tolerance"],
        sample_rate_tolerance=config["validation"]["sample_rate_tolerance"],
    script:
        "../scripts/blind_diagnose.py"


rule blind_score:
    """Verdicts against the truth: scores, targets, confusion matrix (Fig. 17)."""
    input:
        truth="results/blind/truth",
        diagnoses=expand("results/blind/diagnosis/chunk{chunk}", chunk=range(BLIND_CHUNKS)),
    output:
        scores="results/blind/scores.parquet",
        summary="results/blind/summary.json",
        figure=report("results/blind/fig17_blind_confusion.png", caption="../report/blind_confusion.rst",
                      category="blind", labels={"campaign": "blind", "figure": "fig17_blind_confusion"}),
    log:
        "logs/blind/score.log",
    script:
        "../scripts/blind_score.py"
