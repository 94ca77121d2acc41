"""Jobs: what strings the stages together, one module per command's work.

- :mod:`.pipeline`       scenario -> simulation -> animation, events, cameras -> shot (``simulate``);
- :mod:`.filming`        re-filming and evaluating an existing shot (``cameras``, ``metrics``);
- :mod:`.toric_filming`  toric and learned cameras on a shot's characters (``frame``, ``features``);
- :mod:`.templates`      scenarios from the example stages (``new``);
- :mod:`.summary`        what a stage holds (``inspect``);
- :mod:`.validation`     USD's validators and the crowd schemas' rules (``validate``);
- :mod:`.plots`          the pictures the jobs write.

Jobs use every lower package (core, character, sim, events, scenario, cameras, usd, render);
only the command line and the dataset runner use them.
"""
