# Everything a campaign's characteristic and records give apart from the diagnosis, in one job:
# test design check (Fig. 5, 6), the nominal model through the campaign's plan, harmonic records
# (Fig. 15), the static force at v -> 0, fitted models and their comparison (Fig. 13, 14), their
# CSV exports, and the characteristic figures (Fig. 7-12) (isokinetic.stages.analysis.write_analysis).


rule analysis:
    """Design check, nominal model, harmonic records, model fits and the campaign's figures."""
    input:
        ingest=output_path("ingest", "ingest"),
        cases=output_path("characteristic", "cases"),
        windows=output_path("characteristic", "windows"),
        characteristic=output_path("characteristic", "characteristic"),
    output:
        **rule_outputs("analysis"),
    log:
        "logs/{campaign}/analysis.log",
    benchmark:
        benchmark_path("analysis")
    resources:
        **rule_resources("analysis"),
    params:
        **rule_settings(SETTINGS, "analysis"),
        code=code_version("analysis.py"),
        vector_format=VECTOR_FORMAT,
    script:
        "../scripts/analysis.py"
