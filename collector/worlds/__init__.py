"""The simulated worlds: everything lasercal draws or simulates in place of a real bench.

A world stands behind the same interfaces as real hardware (:class:`~lasercal.collector.hardware.base.
RobotAdapter`, a camera's ``read``/``set_exposure``), so a session cannot tell a simulated arm from a real
one. Sessions and the command line reach a world only through the backend factory
(:mod:`lasercal.collector.hardware`), never by importing this package.

* the ``fake`` backend: the arm and the operator (:mod:`.fake`), the arm's hidden effects
  (:mod:`.fakeeffects`), the table's effects and their draws (:mod:`.fakeworld`); the world's own code for
  the arm's beam (:mod:`.truearm`), the paper (:mod:`.truesheet`), the lens (:mod:`.truelens`) and the spot
  (:mod:`.truespot`); its cameras (:mod:`.cameras`); the world a session recorded (:mod:`.record`) (the floors
  measured in it are a study, :mod:`collector.studies.floors`);
* the ``mujoco`` backend: a world file driven as hardware (:mod:`.mujoco`) and the scene writer
  (:mod:`.mujoco_scene`).
"""
