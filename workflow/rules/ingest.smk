rule ingest:
    """Read a raw campaign folder (manifest + CSVs), convert to SI, write canonical Parquet."""
    input:
        raw_files,
    output:
        **rule_outputs("ingest"),
    log:
        "logs/{campaign}/ingest.log",
    benchmark:
        benchmark_path("ingest")
    wildcard_constraints:
        campaign=one_of(RAW_CAMPAIGNS),
    resources:
        **rule_resources("ingest"),
    params:
        campaign_dir=lambda wildcards: str(RAW_DIR / wildcards.campaign),
    script:
        "../scripts/ingest.py"
