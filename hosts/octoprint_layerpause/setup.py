"""OctoPrint-LayerPause: OctoPrint's Pause/Resume/Cancel buttons drive the LayerPause
firmware's own layer pause (M601/M602/M524) instead of OctoPrint's host-side pause."""

from setuptools import setup

setup(
    name="OctoPrint-LayerPause",
    version="0.1.0",
    description="Pause at the next layer boundary (and park) from OctoPrint's Pause button, "
    "pause at layer N, the firmware's pause state and layer counter",
    license="MIT OR Apache-2.0",
    packages=["octoprint_layerpause"],
    python_requires=">=3.8",
    install_requires=["OctoPrint>=1.9"],
    entry_points={"octoprint.plugin": ["layerpause = octoprint_layerpause"]},
)
