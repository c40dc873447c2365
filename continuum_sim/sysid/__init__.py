"""Sim-to-real (SPEC §11): recorded robot data, replay through the model, identification.

* ``data``: the recorded-data CSV format (commands, optional tensions, measured tool pose);
* ``plant``: the single-arm replay model and the one function that turns recorded cable
  set-points into actuator controls (``cable_controls``);
* ``replay``: drives the model with a recording and compares predicted and measured poses;
* ``excitation``: the documented excitation motion and ``synthesize`` (data from the model);
* ``identify``: least squares over simulated replays for any numeric config paths;
* ``ftdcr``: importer of the OpenCR-MuJoCo FTDCR v4 motion-capture recordings.
"""
