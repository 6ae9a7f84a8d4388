# Comparisons of campaigns (config `comparisons`): the same damper before and after a repair, two
# dampers of a batch, two temperatures. One job per comparison reads its campaigns' characteristic and
# fitted models and writes results/compare/<name>/: the table (and its CSV export), the summary,
# Fig. 18-19 and the comparison's page (isokinetic.stages.compare, isokinetic.report.compare_report).
# Without a `comparisons` block there is no such job.


rule compare:
    """Every campaign of a comparison against its first (the reference), per velocity and direction:
    forces, difference, standard error and significance; overlay and difference figures; the page."""
    input:
        unpack(comparison_inputs),
        captions=[f.caption for f in rule_figures("compare")],
    output:
        **rule_outputs("compare", campaign=comparison_folder("{comparison}")),
    log:
        "logs/compare/{comparison}/compare.log",
    benchmark:
        benchmark_path("compare", comparison_folder("{comparison}"))
    wildcard_constraints:
        comparison=one_of(COMPARISONS),
    resources:
        **rule_resources("compare"),
    params:
        code=code_version("compare.py"),
        campaigns=lambda wildcards: COMPARISONS[wildcards.comparison]["campaigns"],
        settings=lambda wildcards: comparison_settings(wildcards.comparison),
        vector_format=VECTOR_FORMAT,
    script:
        "../scripts/compare.py"
