"""``tlfleet init NAME [-o FILE] [--force]``: write a commented starter scenario.

The file has every section a scenario uses, each commented: an arena, three regions, one LTL robot
(a unicycle that visits two regions forever, paper Algorithm 1), two STL robots (omnidirectional;
one reaches a point in a time window, the other stays near it: a coupled task, paper eq. (2)) and
the controller's and simulator's parameters. It passes ``tlfleet check`` as written (a test runs
it), so a new user edits a running example instead of starting from a blank page.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from tlfleet.bus.errors import TlfleetError

NAME = "init"
HELP = "write a commented starter scenario that passes `tlfleet check`"
EXAMPLES = (
    ("tlfleet init warehouse", "write warehouse.toml here, then `tlfleet run warehouse.toml`"),
    ("tlfleet init lab -o scenarios/lab.toml --force", "write or overwrite scenarios/lab.toml"),
)
EXIT_CODES = {0: "the file was written",
              1: "the file exists (use --force) or the name is not a key segment"}

_NAME = re.compile(r"[A-Za-z0-9_-]+\Z")  # the scenario's name is its fleet's key segment

TEMPLATE = '''\
# {name}: a starter scenario written by `tlfleet init` — edit it, then
#   tlfleet check {file}      # validate and summarise (file, field and reason on an error)
#   tlfleet plan {file}       # the LTL robot's optimal prefix-suffix plan
#   tlfleet run {file}        # run the fleet; report, figures and run.rrd at the end
# The paper's scenarios are bundled for comparison: `tlfleet run scenario1` (scenario2, scenario3).
# Units: positions and radii [m], angles [rad], times [s], rates [Hz].

name = "{name}"              # also the fleet's name in the zenoh keys (tlfleet/{name}/...)
description = "one LTL robot patrols two regions; two STL robots meet and keep close"
duration = 60.0              # sim time of a run [s]

[arena]                      # the walls of the rectangle the robots move in [m]
xmin = -3.0
xmax = 3.0
ymin = -3.0
ymax = 3.0

[sim]
mocap_rate = 100.0           # motion-capture frames a second [Hz]
disturbance = 0.0            # bound of a random velocity disturbance [m/s]
mocap_noise = 0.0            # standard deviation of the pose noise [m]
seed = 1                     # the simulator's random seed (a lockstep run repeats exactly)

[ltl]
suffix_weight = 10.0         # β of the plan's cost, prefix + β·suffix (paper Algorithm 1)
control_rate = 5.0           # LTL robots' control rate [Hz]

[stl]                        # the funnel controller of the STL robots (paper §III-B)
eta = 10.0
n_stage1 = 2
delta = 0.02
zeta_l = 0.2
r1 = 0.6
r_sense = 0.7                # sensing radius for collision avoidance [m]
beta = 2.0
control_rate = 100.0         # STL robots' control rate [Hz]

# Regions: the atomic propositions of the LTL tasks are their names.
[[regions]]
name = "dock"
center = [-1.5, -1.5]
radius = 0.3

[[regions]]
name = "shelf"
center = [1.0, 0.5]
radius = 0.3

[[regions]]
name = "desk"
center = [-2.0, 2.0]
radius = 0.3

# An LTL robot (a unicycle): visit dock and shelf again and again, never desk.
[[robots]]
id = 1
kind = "unicycle"
pose = [-1.5, -2.5, 1.5707963267948966]   # x [m], y [m], heading [rad]
ltl = "G F dock & G F shelf & G !desk"

# Two STL robots (omnidirectional). pN is robot N's position; dist(a, b) a Euclidean distance.
# Robot 2 reaches the point (1, -1) between 10 and 20 s ...
[[robots]]
id = 2
kind = "omni"
pose = [0.0, -2.5, 0.0]
stl = ["F[10,20] (dist(p2, [1,-1]) <= 0.2)"]

# ... and robot 3 stays within 1 m of robot 2 from 25 to 35 s: a task that couples two robots.
[[robots]]
id = 3
kind = "omni"
pose = [2.5, -2.0, 0.0]
stl = ["G[25,35] (dist(p3, p2) <= 1)"]
'''


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", help="the scenario's name (letters, digits, _ and -)")
    parser.add_argument("-o", "--out", type=Path, default=None, metavar="FILE",
                        help="where to write it (default NAME.toml in this directory)")
    parser.add_argument("--force", action="store_true", help="overwrite an existing file")


def starter(name: str, file: str) -> str:
    """The starter scenario's text for ``name`` (its file shown as ``file`` in the comments)."""
    if not _NAME.match(name):
        raise TlfleetError(f"scenario name {name!r}: use letters, digits, _ and - (it is the "
                           "fleet's key segment)")
    return TEMPLATE.format(name=name, file=file)


def run(args: argparse.Namespace) -> int:
    out = args.out if args.out is not None else Path(f"{args.name}.toml")
    text = starter(args.name, str(out))
    if out.exists() and not args.force:
        raise TlfleetError(f"{out} exists: choose another name or -o FILE, or add --force")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(f"wrote {out}: check it with `tlfleet check {out}`, run it with `tlfleet run {out}`",
          file=sys.stderr)
    return 0
