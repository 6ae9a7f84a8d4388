# Everything a campaign's characteristic and records give apart from the diagnosis, in one job:
# test design check (Fig. 5, 6), the nominal model through the campaign's plan, harmonic records
# (Fig. 15), the static force at v -> 0, fitted models and their comparison (Fig. 13, 14), their
# CSV exports, and the characteristic figures (Fig. 7-12) (isokinetic.stages.analysis.write_analysis).
#
# Why seven stages share one job (issue 36): every stage here reads the same few tables and is cheap next to
# a job's start (a fresh Python importing pandas, scipy and matplotlib: about 0.5 CPU-s, docs/benchmarks.md),
# and four of the seven draw figures (design Fig. 5-6, harmonic Fig. 15, models Fig. 13-14, figures Fig. 7-12).
# Code changes rerun the job by its import closure (param code), so editing a figure's module also reruns the
# model fits; but the fits are weighted least squares on a few dozen points (about 10 ms for 36 windows),
# while a job of their own would add a job start to every campaign of every build. Not split, for that reason.


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
