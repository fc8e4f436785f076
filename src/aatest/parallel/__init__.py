"""Process-level compute shared by the analysis pass, diagnose and the analyses.

- ``forked``     map a function over forked worker processes that inherit the caller's state
                 (the registered reductions of a recording's lazy steps), one per CPU
- ``gc_freeze``  keep the objects that exist before a long computation out of the garbage
                 collector's scans

Below the engine: nothing here imports the engine, a plugin or a recording.
"""
