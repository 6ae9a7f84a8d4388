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
        **rule_settings(SETTINGS, "characteristic"),
        code=code_version("characteristic.py"),
    script:
        "../scripts/characteristic.py"
