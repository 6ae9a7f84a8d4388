# Reports for people: one self-contained HTML page per campaign (figures embedded, no server, no
# network) and results/index.html over all campaigns and the blind suite. Every number on the pages
# names its source file, rule, commit and parameters (isokinetic.report).


rule campaign_report:
    """The campaign's report page: plan check, characteristic, repeatability, models, harmonic,
    design, diagnosis and quarantine, every figure embedded, every number with its lineage."""
    input:
        ingest="results/{campaign}/ingest",
        cases="results/{campaign}/cases.parquet",
        quarantine="results/{campaign}/quarantine.parquet",
        characteristic="results/{campaign}/characteristic.parquet",
        repeatability="results/{campaign}/repeatability.parquet",
        plan_check="results/{campaign}/design/plan_check.parquet",
        models="results/{campaign}/models/models.parquet",
        comparison="results/{campaign}/models/comparison.parquet",
        harmonic="results/{campaign}/harmonic/harmonic.parquet",
        diagnosis="results/{campaign}/diagnosis.json",
        figures=[f"results/{{campaign}}/{f.path}" for f in FIGURES if f.rule != "blind_score"],
        captions=[f.caption for f in FIGURES if f.rule != "blind_score"],
        provenance=provenance_if_made,
    output:
        **rule_outputs("campaign_report"),
    log:
        "logs/{campaign}/campaign_report.log",
    wildcard_constraints:
        campaign=one_of(CAMPAIGNS),
    script:
        "../scripts/campaign_report.py"


rule report_index:
    """results/index.html: every campaign's verdict and key numbers, linked to its page; the blind suite."""
    input:
        reports=expand("results/{campaign}/report.html", campaign=CAMPAIGNS),
        diagnoses=expand("results/{campaign}/diagnosis.json", campaign=CAMPAIGNS),
        blind=BLIND_OUTPUTS if config.get("blind") else [],
        captions=[f.caption for f in figures_of("blind_score")],
    output:
        "results/index.html",
    log:
        "logs/report_index.log",
    params:
        campaigns=CAMPAIGNS,
        blind_dir=lambda wildcards, input: str(Path(input.blind[0]).parent) if input.blind else None,
    script:
        "../scripts/report_index.py"
