# Reports for people: one self-contained HTML page per campaign (figures embedded, no server, no
# network), with the raw check (raw_check.json: every raw file the ingest read still has the sha256
# recorded then; a changed raw file fails this job) and the campaign's provenance record written first
# in the same job (one job fewer per campaign than a raw-check job of its own: issue 23), and
# results/index.html over all campaigns, the blind suite and the comparisons (their pages are written
# by rule compare), with every campaign's plan check in one table. Every number on the pages names its
# source file, rule, commit and parameters (isokinetic.report). The index never waits on every campaign:
# after a failed run the onerror handler rebuilds it from what exists (common.smk, report_failed_run).


rule campaign_report:
    """raw_check.json (every raw file the campaign's ingest read still has the sha256 recorded then:
    isokinetic.audit.raw_check; a changed or missing one fails the job), provenance.json (raw files and
    hashes, environment, code, stages of every output), then the campaign's report page: plan check,
    characteristic, repeatability, models, harmonic, design, diagnosis and quarantine, every figure
    embedded, every number with its lineage."""
    input:
        raw=lambda wildcards: raw_files(wildcards) if wildcards.campaign in RAW_CAMPAIGNS else [],
        outputs=lambda wildcards: campaign_outputs(wildcards.campaign),
        ingest=output_path("ingest", "ingest"),
        cases=output_path("characteristic", "cases"),
        comparison=output_path("analysis", "comparison"),
        plan_check=output_path("analysis", "plan_check"),
        captions=[f.caption for f in FIGURES if f.stage not in ("blind_score", "compare")],
    output:
        **rule_outputs("campaign_report"),
    log:
        "logs/{campaign}/campaign_report.log",
    benchmark:
        benchmark_path("campaign_report")
    wildcard_constraints:
        campaign=one_of(ACTIVE),
    resources:
        **rule_resources("campaign_report"),
    params:
        code=code_version("campaign_report.py"),
    script:
        "../scripts/campaign_report.py"


rule report_index:
    """results/index.html: every campaign's verdict and key numbers, linked to its page (an interrupted
    one shown interrupted); apart, the folders under the raw data folder it does not build and the orphaned
    results; the blind suite; each comparison, linked to its page; and results/design/plan_check.parquet,
    every campaign's plan check in one table."""
    input:
        reports=expand(output_path("campaign_report", "page"), campaign=ACTIVE),
        diagnoses=expand(output_path("diagnosis", "json"), campaign=ACTIVE),
        plan_checks=expand(output_path("analysis", "plan_check"), campaign=ACTIVE),
        blind=BLIND_OUTPUTS if config.get("blind") else [],
        comparisons=comparison_pages(),
        captions=[f.caption for f in rule_figures("blind_score")],
    output:
        index="results/index.html",
        design_summary=DESIGN_SUMMARY,
    log:
        "logs/report_index.log",
    benchmark:
        "logs/report_index.benchmark.tsv"
    resources:
        **rule_resources("report_index"),
    params:
        code=code_version("report_index.py"),
        campaigns=CAMPAIGNS,
        raw_dirs={campaign: str(RAW_DIR / campaign) for campaign in RAW_CAMPAIGNS if campaign not in REFUSED},
        blind_dir=lambda wildcards, input: str(Path(input.blind[0]).parent) if input.blind else None,
        comparisons=list(COMPARISONS),
        refused=REFUSED,
        unusable=UNUSABLE,
        orphaned=ORPHANED,
    script:
        "../scripts/report_index.py"
