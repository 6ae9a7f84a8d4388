# Blind test of the diagnosis on withheld effects: one generation job, the diagnosis in a fixed
# number of chunks (each job starts Python once and diagnoses its share of the scenarios), one
# scoring job. Only blind_score reads the truth. The suite is the longest chain of the default build,
# so its jobs go first (priority) and the campaigns' jobs fill the other core.


rule blind_generate:
    """Blind scenarios: raw campaigns without their truth, and the truth kept apart for scoring."""
    output:
        raw=directory(f"{BLIND_ROOT}/raw"),
        truth=directory(f"{BLIND_ROOT}/truth"),
    log:
        "logs/blind/generate.log",
    benchmark:
        benchmark_path("blind_generate", BLIND_DIR)
    priority: 10
    resources:
        **rule_resources("blind_generate"),
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
        f"{BLIND_ROOT}/raw",
    output:
        directory(f"{BLIND_ROOT}/diagnosis/chunk{{chunk}}"),
    log:
        "logs/blind/diagnose-chunk{chunk}.log",
    benchmark:
        benchmark_path("blind_diagnose-chunk{chunk}", BLIND_DIR)
    wildcard_constraints:
        chunk=r"\d+",
    priority: 10
    resources:
        **rule_resources("blind_diagnose"),
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
        truth=f"{BLIND_ROOT}/truth",
        diagnoses=expand(f"{BLIND_ROOT}/diagnosis/chunk{{chunk}}", chunk=range(BLIND_CHUNKS)),
    output:
        **rule_outputs("blind_score", campaign=BLIND_DIR),
    log:
        "logs/blind/score.log",
    benchmark:
        benchmark_path("blind_score", BLIND_DIR)
    resources:
        **rule_resources("blind_score"),
    params:
        vector_format=VECTOR_FORMAT,
    script:
        "../scripts/blind_score.py"
