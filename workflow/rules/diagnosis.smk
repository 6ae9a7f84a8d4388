rule diagnosis:
    """Sim-to-real gap: where it lies, which effect causes it, how far it shrinks (diagnosis.json)."""
    input:
        cases=output_path("characteristic", "cases"),
        ingest=output_path("ingest", "ingest"),
        characteristic=output_path("characteristic", "characteristic"),
        windows=output_path("characteristic", "windows"),
    output:
        **rule_outputs("diagnosis"),
    log:
        "logs/{campaign}/diagnosis.log",
    benchmark:
        benchmark_path("diagnosis")
    resources:
        **rule_resources("diagnosis"),
    params:
        **rule_settings(SETTINGS, "diagnosis"),
        code=code_version("diagnosis.py"),
        vector_format=VECTOR_FORMAT,
    script:
        "../scripts/diagnosis.py"
