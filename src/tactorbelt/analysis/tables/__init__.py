"""The tables room: stores loaded into pandas (``load``, ``dataset``), the study design
(``design``), the descriptive tables (``tables``), per-cell results and information
transfer (``cells``, ``transfer``), the classical tests (``classical``), secondary tasks
and the NASA-TLX (``tasks``), wearer-profile effects (``profiles``).

The bottom analysis room: imports no other analysis room.
"""
