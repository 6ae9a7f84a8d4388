rule raw_check:
    """Every raw file the campaign's ingest read still has the sha256 recorded at ingest
    (isokinetic.audit.raw_check; the same comparison as provenance.json's raw section)."""
    input:
        raw=raw_files,
        cases=output_path("characteristic", "cases"),
        ingest=output_path("ingest", "ingest"),
    output:
        **rule_outputs("raw_check"),
    log:
        "logs/{campaign}/raw_check.log",
    benchmark:
        benchmark_path("raw_check")
    wildcard_constraints:
        campaign=one_of([c for c in RAW_CAMPAIGNS if c not in REFUSED]),
    resources:
        **rule_resources("raw_check"),
    script:
        "../scripts/raw_check.py"
