rule raw_check:
    """Every raw file the campaign's ingest read still has the sha256 recorded at ingest
    (isokinetic.audit.raw_check; the same comparison as provenance.json's raw section)."""
    input:
        raw=raw_files,
        cases="results/{campaign}/cases.parquet",
        ingest="results/{campaign}/ingest",
    output:
        **rule_outputs("raw_check"),
    log:
        "logs/{campaign}/raw_check.log",
    wildcard_constraints:
        campaign=one_of(RAW_CAMPAIGNS),
    script:
        "../scripts/raw_check.py"
