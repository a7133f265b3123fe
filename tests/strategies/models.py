"""Small PRISM MDPs whose optimal strategies are worth exporting, with properties.

Each case is a model text and one property; the optimum is known by hand where the
comment says so, and Storm confirms every one (``test_induced.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Case:
    """One MDP and one property whose strategy is exported."""

    name: str
    model: str
    prop: str
    #: The optimum at the initial state(s), solved by hand (None: Storm's word only).
    expected: float | tuple[float, float] | None = None

    @property
    def storm_prop(self) -> str | None:
        """The property as Storm's parser reads it (None: it reads no W, R or R{k})."""
        unreadable = (" W ", " R ", "R{2}")
        return None if any(u in self.prop for u in unreadable) else self.prop

    def __str__(self) -> str:
        return self.name


#: East moves one cell with 0.8; risky jumps to the goal or breaks down with 0.5 each.
ROBOT = """mdp
const int N = 3;
module robot
  x : [0..N] init 0;
  done : bool init false;
  [east] x<N & !done -> 0.8:(x'=x+1) + 0.2:(x'=x);
  [risky] x<N & !done -> 0.5:(x'=N) + 0.5:(done'=true);
  [stay] x=N -> true;
endmodule
label "goal" = x=N;
label "broken" = done;
rewards "steps"
  [east] true : 1;
  [risky] true : 2;
endrewards
rewards "time"
  x<N : 1;
endrewards
"""

#: An end component {0, 1}: Pmax must leave it through exit (0.5), not loop (0).
LOOP = """mdp
module m
  s : [0..4] init 0;
  [loop] s=0 -> (s'=1);
  [back] s=1 -> (s'=0);
  [exit] s=1 -> 0.5:(s'=2) + 0.5:(s'=3);
  [try] s=0 -> 0.3:(s'=2) + 0.7:(s'=4);
  [] s>=2 -> true;
endmodule
label "goal" = s=2;
rewards
  s<2 : 1;
  [exit] true : 0.5;
endrewards
"""

#: Two modules synchronising on go and jump, an unlabelled choice, two initial states.
SYNC = """mdp
module a
  x : [0..2];
  [go] x<2 -> 0.6:(x'=x+1) + 0.4:(x'=0);
  [jump] x=0 -> (x'=2);
  [] x=1 -> 0.5:(x'=2) + 0.5:(x'=0);
endmodule
module b
  y : bool;
  [go] true -> (y'=!y);
  [jump] !y -> true;
endmodule
init x=0 | (x=1 & !y) endinit
label "top" = x=2;
rewards "cost"
  [go] true : 1;
  [jump] true : 3;
  [] y : 0.25;
endrewards
rewards "time"
  x<2 : 1;
endrewards
"""

#: A walk on -2..2; z=2 is a deadlock (no command), fixed with a self-loop.
WALK = """mdp
module walk
  z : [-2..2] init 0;
  [l] z>-2 & z<2 -> 0.5:(z'=z-1) + 0.5:(z'=z);
  [r] z<2 -> 0.25:(z'=z+1) + 0.75:(z'=z);
endmodule
label "left" = z=-2;
label "right" = z=2;
"""

#: A zero-reward end component {0} (stay) beside a paying cycle: Rmax must leave it.
IDLE = """mdp
module m
  s : [0..2] init 0;
  [stay] s=0 -> true;
  [go] s=0 -> (s'=1);
  [hop] s=1 -> 0.5:(s'=0) + 0.5:(s'=2);
  [] s=2 -> true;
endmodule
rewards
  [go] true : 1;
endrewards
"""

CASES = (
    Case("robot-pmax", ROBOT, 'Pmax=? [ F "goal" ]', 1.0),
    Case("robot-pmin", ROBOT, 'Pmin=? [ F "goal" ]', 0.5),
    Case("robot-rmin", ROBOT, 'R{"steps"}min=? [ F "goal" ]', 3.75),
    Case("robot-tmin", ROBOT, 'Tmin=? [ F "goal" ]', 3.75),  # Storm's expected steps: east
    Case("robot-rmax-time", ROBOT, 'R{"time"}max=? [ F "goal" ]', math.inf),  # risky breaks
    Case("robot-pmax-globally", ROBOT, 'Pmax=? [ G !"broken" ]', 1.0),
    Case("robot-bounded-p", ROBOT, 'P>=0.4 [ F "goal" ]', 0.5),
    Case("loop-pmax", LOOP, 'Pmax=? [ F "goal" ]', 0.5),
    Case("loop-pmin", LOOP, 'Pmin=? [ F "goal" ]', 0.0),
    Case("loop-until", LOOP, 'Pmax=? [ s<=1 U s=3 ]', 0.5),
    Case("loop-rmin-total", LOOP, "Rmin=? [ C ]", 1.0),  # try: one step in s=0
    Case("loop-rmax-reach", LOOP, 'Rmax=? [ F s>=2 ]', math.inf),  # loop forever
    Case("sync-rmin", SYNC, 'R{"cost"}min=? [ F "top" ]'),
    Case("sync-rmax", SYNC, 'R{"cost"}max=? [ F "top" ]'),
    Case("sync-total-time", SYNC, 'R{2}max=? [ C ]'),
    Case("sync-pmin-weak", SYNC, 'Pmin=? [ x<2 W y ]'),
    Case("walk-pmax-until", WALK, 'Pmax=? [ !"left" U "right" ]'),
    Case("walk-pmin-release", WALK, 'Pmin=? [ "right" R z>=-1 ]'),
    Case("walk-pmax-globally", WALK, 'Pmax=? [ G z>-2 ]', 1.0),
    Case("idle-rmax-total", IDLE, "Rmax=? [ C ]", 2.0),  # go pays 1, comes back half the time
    Case("idle-rmin-total", IDLE, "Rmin=? [ C ]", 0.0),  # stay forever
    Case("idle-pmin-globally", IDLE, "Pmin=? [ G s<2 ]", 0.0),  # go, hop until s=2
)
