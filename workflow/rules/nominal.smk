rule nominal:
    """The nominal model (campaign.yaml damper data) run through the campaign's own plan and windows."""
    input:
        cases="results/{campaign}/cases.parquet",
        ingest="results/{campaign}/ingest",
        windows="results/{campaign}/windows.parquet",
    output:
        **rule_outputs("nominal"),
    log:
        "logs/{campaign}/nominal.log",
    params:
        start_fraction=config["windows"]["start_fraction"],
        end_fraction=config["windows"]["end_fraction"],
    script:
        "../scripts/nominal.py"
