"""The analysis pass's per-step work, made during the record phase in a child process.

- ``analysis``  the run's side: starts the child at the start of the record phase, hands it
                each step file as it is written, collects what it made (``aatest run``)
- ``child``     the child's loop: each step (handed, else decoded from its file) analysed
                as the pass will
- ``handover``  a step's logs in shared memory, exactly as a decode of its file gives them
- ``made``      what crosses the pipe: a step's results with the digests that say which
                recorded bytes, plan and analyses they are of

Below the engine's run package (which starts it) and above the analysis pass (whose watches
it registers): it never imports :mod:`aatest.engine.run`.
"""
