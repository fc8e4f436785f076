"""Running a plan on a rig.

- ``rig``        builds the rig's plugins; safe stop (table stopped, motor off) on any fault
- ``runner``     the step loop: record, persist, resume without repeating a step
- ``writes``     step files written on a worker thread while the next step records
- ``run_state``  ``run_state.json``: which steps are done, which prompts were shown
- ``progress``   the operator's terminal progress line
- ``session``    what each CLI command does, end to end, without CLI concerns
"""
