rule virtual_rig:
    """Simulate a config-defined campaign into the ingested-campaign layout."""
    output:
        **rule_outputs("virtual_rig"),
    log:
        "logs/{campaign}/virtual_rig.log",
    benchmark:
        benchmark_path("virtual_rig")
    wildcard_constraints:
        campaign=one_of([c for c in VIRTUAL_CAMPAIGNS if c not in REFUSED]),
    resources:
        **rule_resources("virtual_rig"),
    params:
        code=code_version("virtual_rig.py"),
        spec=lambda wildcards: config["virtual_campaigns"][wildcards.campaign],
    script:
        "../scripts/virtual_rig.py"
