# Reports for people: one self-contained HTML page per campaign (figures embedded, no server, no
# network) and results/index.html over all campaigns and the blind suite. Every number on the pages
# names its source file, rule, commit and parameters (isokinetic.report).

REPORT_CAPTIONS = [f"workflow/report/{name}.rst" for name in FIGURES + DESIGN_FIGURES + MODEL_FIGURES
                   + ["fig15_harmonic_loops", "fig16_gap"]]


def provenance_if_made(wildcards):
    """results/<campaign>/provenance.json when a rule of the workflow makes it. Not when the campaign's
    outputs (which the provenance rule reads) include the page itself: that would be a cycle."""
    path = f"results/{wildcards.campaign}/provenance.json"
    if any(str(p).endswith("/report.html") for p in campaign_outputs(wildcards.campaign)):
        return []
    return [path] if any(r.is_producer(path) for r in workflow.rules if r.name != "campaign_report") else []


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
        figures=[f"results/{{campaign}}/figures/{name}.png" for name in FIGURES]
        + [f"results/{{campaign}}/design/{name}.png" for name in DESIGN_FIGURES]
        + [f"results/{{campaign}}/models/{name}.png" for name in MODEL_FIGURES]
        + ["results/{campaign}/harmonic/fig15_harmonic_loops.png", "results/{campaign}/diagnosis/fig16_gap.png"],
        captions=REPORT_CAPTIONS,
        provenance=provenance_if_made,
    output:
        "results/{campaign}/report.html",
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
        captions="workflow/report/blind_confusion.rst",
    output:
        "results/index.html",
    log:
        "logs/report_index.log",
    params:
        campaigns=CAMPAIGNS,
        blind_dir="results/blind" if config.get("blind") else None,
    script:
        "../scripts/report_index.py"
