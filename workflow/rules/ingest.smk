rule ingest:
    """Read a raw campaign folder (manifest + CSVs), convert to SI, write canonical Parquet. Its inputs are
    the manifest and the case files it names, nothing else of the folder (common.smk raw_files)."""
    input:
        raw_files,
    output:
        **rule_outputs("ingest"),
    log:
        "logs/{campaign}/ingest.log",
    benchmark:
        benchmark_path("ingest")
    wildcard_constraints:
        campaign=one_of([c for c in RAW_CAMPAIGNS if c not in REFUSED]),
    resources:
        **rule_resources("ingest"),
    params:
        **rule_settings(SETTINGS, "ingest"),
        code=code_version("ingest.py"),
        campaign_dir=lambda wildcards: str(RAW_DIR / wildcards.campaign),
        raw_dir=str(RAW_DIR),
        # files named with pattern characters, which Snakemake cannot take as inputs: size and mtime
        untracked=raw_fingerprints,
    script:
        "../scripts/ingest.py"
