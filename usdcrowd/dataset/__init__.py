"""Datasets at scale: many randomized sequences, simulated, filmed, rendered and merged into MOT and COCO.

- :mod:`.spec`: the TOML spec and the seeded plan of each sequence;
- :mod:`.scenario`: one sequence from its plan to a filmed shot;
- :mod:`.run`: the tasks, their executors (inline, local processes, Ray) and the merge;
- :mod:`.layout`: MOTChallenge folders, seqmaps and COCO per split;
- :mod:`.card`: the dataset card (README.md, card.png);
- :mod:`.baseline`: a simple IoU tracker to check the evaluation end to end.
"""
