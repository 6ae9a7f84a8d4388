# The steady characteristic of a campaign in one job (one Python start-up): validate -> windows ->
# repeatability -> characteristic (isokinetic.stages.characteristic.write_characteristic).


rule characteristic:
    """Per case checks (failing cases quarantined with their reason), the mean force and velocity of
    every constant-velocity window, period 1 against period 2, and the steady force-velocity points."""
    input:
        output_path("ingest", "ingest"),
    output:
        **rule_outputs("characteristic"),
    log:
        "logs/{campaign}/characteristic.log",
    benchmark:
        benchmark_path("characteristic")
    resources:
        **rule_resources("characteristic"),
    params:
        code=code_version("characteristic.py"),
        sample_rate_tolerance=config["validation"]["sample_rate_tolerance"],
        max_missing_fraction=config["validation"]["max_missing_fraction"],
        max_gap_s=config["validation"]["max_gap_s"],
        start_fraction=config["windows"]["start_fraction"],
        end_fraction=config["windows"]["end_fraction"],
        repeatability_tolerance=config["repeatability"]["tolerance"],
    script:
        "../scripts/characteristic.py"
