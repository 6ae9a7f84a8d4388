rule repeatability:
    """Period 1 against period 2 per case and direction."""
    input:
        "results/{campaign}/windows.parquet",
    output:
        **rule_outputs("repeatability"),
    log:
        "logs/{campaign}/repeatability.log",
    params:
        tolerance=config["repeatability"]["tolerance"],
    script:
        "../scripts/repeatability.py"
