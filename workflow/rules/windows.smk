rule windows:
    """Mean force, its spread and the piston velocity in each constant-velocity window."""
    input:
        cases="results/{campaign}/cases.parquet",
        ingest="results/{campaign}/ingest",
    output:
        **rule_outputs("windows"),
    log:
        "logs/{campaign}/windows.log",
    params:
        start_fraction=config["windows"]["start_fraction"],
        end_fraction=config["windows"]["end_fraction"],
    script:
        "../scripts/windows.py"
