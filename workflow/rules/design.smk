rule design:
    """Test design per case: G-numbers, stroke to converge, plan check; Fig. 5 and Fig. 6."""
    input:
        cases="results/{campaign}/cases.parquet",
        ingest="results/{campaign}/ingest",
    output:
        **rule_outputs("design"),
    log:
        "logs/{campaign}/design.log",
    params:
        phi=config["design"]["convergence_fraction"],
        max_amplitude_m=config["design"]["max_amplitude_mm"] * 1e-3,
        min_amplitude_m=config["design"]["min_amplitude_mm"] * 1e-3,
        start_fraction=config["windows"]["start_fraction"],
    script:
        "../scripts/design.py"


rule design_summary:
    """All campaigns' plan checks in one table."""
    input:
        expand("results/{campaign}/design/plan_check.parquet", campaign=CAMPAIGNS),
    output:
        "results/design/plan_check.parquet",
    log:
        "logs/design_summary.log",
    script:
        "../scripts/design_summary.py"
