"""``python -m isokinetic init-campaign FOLDER``: a ``campaign.yaml`` drafted from a folder of case CSV files.

:mod:`.sniff` finds each file's dialect, comment lines and header; :mod:`.channels` guesses the role and unit
of each column from its name and from its magnitudes; :mod:`.waveform` detects each record's triangle, sine
or free excitation; :mod:`.survey` reads the folder and makes the campaign-level choices; :mod:`.draft`
writes the commented draft; :mod:`.check` (``--check``) compares a folder with its existing manifest.
Nothing but ``FOLDER/campaign.yaml`` is ever written, and an existing one only with ``--force``.
"""
