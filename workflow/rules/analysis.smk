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
        code=code_version("analysis.py"),
        phi=config["design"]["convergence_fraction"],
        max_amplitude_m=config["design"]["max_amplitude_mm"] * 1e-3,
        min_amplitude_m=config["design"]["min_amplitude_mm"] * 1e-3,
        start_fraction=config["windows"]["start_fraction"],
        end_fraction=config["windows"]["end_fraction"],
        vector_format=VECTOR_FORMAT,
    script:
        "../scripts/analysis.py"
