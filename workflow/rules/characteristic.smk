rule characteristic:
    """The steady force-velocity characteristic of the campaign."""
    input:
        windows="results/{campaign}/windows.parquet",
        repeatability="results/{campaign}/repeatability.parquet",
    output:
        **rule_outputs("characteristic"),
    log:
        "logs/{campaign}/characteristic.log",
    script:
        "../scripts/characteristic.py"
