"""Sim-to-real (SPEC §11): recorded robot data, replay through the model, identification.

* ``data``: the recorded-data CSV format (commands, optional tensions, measured tool pose);
* ``plant``: the single-arm replay model and the one function that turns recorded cable
  set-points into actuator controls (``cable_controls``);
* ``replay``: drives the model with a recording and compares predicted and measured poses;
* ``excitation``: the documented excitation motion and ``synthesize`` (data from the model);
* ``identify``: least squares over simulated replays for any numeric config paths;
* ``calibrate``: tendon angles from single-tendon pulls (``identify --calibrate-angles``);
* ``opencr``: importer of OpenCR-style motion-capture sessions of any robot of that family;
* ``robot``: an OpenCR generation JSON as a scenario TOML;
* ``cli``, ``import_cli``: the subcommands.
"""
