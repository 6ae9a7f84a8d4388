rule provenance:
    """Where the campaign's numbers came from: raw files and their hashes, environment, code, stages."""
    input:
        lambda wildcards: campaign_outputs(wildcards.campaign),
    output:
        **rule_outputs("provenance"),
    log:
        "logs/{campaign}/provenance.log",
    wildcard_constraints:
        campaign=one_of(CAMPAIGNS),
    script:
        "../scripts/provenance.py"
