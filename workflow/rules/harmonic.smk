rule harmonic:
    """Harmonic (sine) and free-waveform records: loops, peak-to-peak and binned characteristics."""
    input:
        cases="results/{campaign}/cases.parquet",
        ingest="results/{campaign}/ingest",
    output:
        **rule_outputs("harmonic"),
    log:
        "logs/{campaign}/harmonic.log",
    script:
        "../scripts/harmonic.py"
