rule figures:
    """The campaign's figures (paper Fig. 7-12 equivalents)."""
    input:
        cases="results/{campaign}/cases.parquet",
        ingest="results/{campaign}/ingest",
        windows="results/{campaign}/windows.parquet",
        characteristic="results/{campaign}/characteristic.parquet",
    output:
        **rule_outputs("figures"),
    log:
        "logs/{campaign}/figures.log",
    script:
        "../scripts/figures.py"
