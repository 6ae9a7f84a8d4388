"""``python -m isokinetic init-campaign FOLDER``: a ``campaign.yaml`` drafted from a folder of case files.

:mod:`.survey` finds the case files (subfolders too, every file passed over listed), reads each with the
format's reader (:mod:`isokinetic.rawfile`: its format, encoding and units row sniffed by
:func:`isokinetic.rawfile.sniff_format`) and makes the campaign-level choices; :mod:`.channels` guesses the
role and unit of each column from its name, its units-row cell and its magnitudes, never takes a column in
volts for a scaled quantity, and checks the roles by physics (a damper's force follows its velocity);
:mod:`.waveform` detects each record's triangle, sine or free excitation; :mod:`.steps` cuts a stepped
record (a sweep, standstills) into one case per step; :mod:`.draft` writes the commented draft;
:mod:`.check` (``--check``) compares a folder with its existing manifest, the column choice included.
:mod:`.sniff` holds the column parser (and the older dialect sniffer). Nothing but ``FOLDER/campaign.yaml``
is ever written, and an existing one only with ``--force``.
"""
