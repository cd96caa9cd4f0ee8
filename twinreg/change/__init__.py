"""The twin over time: what each survey saw (:mod:`.observed`, written by every build-twin run), and ``compare``:
the epochs read back (:mod:`.epochs`), aligned (:mod:`.align`), their objects paired (:mod:`.pairs`) and given a
status (:mod:`.status`), with tracks and occupancy (:mod:`.tracks`) and the outputs (:mod:`.outputs`,
:mod:`.report`)."""
