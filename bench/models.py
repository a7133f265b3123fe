"""Scalable DTMC families for the benchmark, written out as PRISM text."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class BenchModel:
    """A benchmark model instance: PRISM text, properties, and a display name."""

    family: str
    size: str
    model: str
    properties: str


def grid_walk(n: int) -> BenchModel:
    """A drifting random walk on an n-by-n grid (n² states, BFS depth 2n)."""
    model = f"""dtmc
const int N = {n};
module walker
  x : [0..N-1] init 0;
  y : [0..N-1] init 0;
  [] !(x=N-1 & y=N-1) -> 0.4:(x'=min(x+1,N-1)) + 0.3:(y'=min(y+1,N-1))
                       + 0.2:(x'=max(x-1,0)) + 0.1:(y'=max(y-1,0));
endmodule
label "goal" = x=N-1 & y=N-1;
rewards "steps"
  true : 1;
endrewards
"""
    props = 'P=? [ F<=100 "goal" ];\nR{"steps"}=? [ F "goal" ];\n'
    return BenchModel("grid", f"N={n}", model, props)


def counters(modules: int, top: int) -> BenchModel:
    """*modules* counters in lock-step on one action, each advancing w.p. 1/2.

    (top+1)^modules states.
    """
    body = [f"dtmc\nconst int K = {top};\n"]
    for i in range(modules):
        body.append(
            f"module c{i}\n  x{i} : [0..K] init 0;\n"
            f"  [tick] x{i}<K -> 0.5:(x{i}'=x{i}+1) + 0.5:true;\n"
            f"  [tick] x{i}=K -> true;\nendmodule\n"
        )
    done = " & ".join(f"x{i}=K" for i in range(modules))
    body.append(f'label "done" = {done};\n')
    props = 'P=? [ F "done" ];\nP=? [ F<=50 "done" ];\n'
    return BenchModel("counters", f"M={modules},K={top}", "".join(body), props)
