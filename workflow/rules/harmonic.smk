rule harmonic:
    """Harmonic (sine) and free-waveform records: loops, peak-to-peak and binned characteristics."""
    input:
        cases="results/{campaign}/cases.parquet",
        ingest="results/{campaign}/ingest",
    output:
        table="results/{campaign}/harmonic/harmonic.parquet",
        figure=report("results/{campaign}/harmonic/fig15_harmonic_loops.png",
                      caption="../report/fig15_harmonic_loops.rst", category="{campaign}",
                      labels={"campaign": "{campaign}", "figure": "fig15_harmonic_loops"}),
    log:
        "logs/{campaign}/harmonic.log",
    script:
        "../scripts/harmonic.py"
