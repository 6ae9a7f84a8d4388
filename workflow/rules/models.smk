rule models:
    """Nominal families, fitted Wallaschek/Surace models and the comparison (Fig. 13, 14)."""
    input:
        characteristic="results/{campaign}/characteristic.parquet",
        nominal="results/{campaign}/nominal_windows.parquet",
        harmonic="results/{campaign}/harmonic/harmonic.parquet",
        ingest="results/{campaign}/ingest",
    output:
        **rule_outputs("models"),
    log:
        "logs/{campaign}/models.log",
    params:
        start_fraction=config["windows"]["start_fraction"],
        end_fraction=config["windows"]["end_fraction"],
    script:
        "../scripts/models.py"
