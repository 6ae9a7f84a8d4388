rule validate:
    """Schema and plan checks per case; failing cases are quarantined with their reason."""
    input:
        "results/{campaign}/ingest",
    output:
        **rule_outputs("validate"),
    log:
        "logs/{campaign}/validate.log",
    params:
        sample_rate_tolerance=config["validation"]["sample_rate_tolerance"],
        start_fraction=config["windows"]["start_fraction"],
        end_fraction=config["windows"]["end_fraction"],
    script:
        "../scripts/validate.py"
