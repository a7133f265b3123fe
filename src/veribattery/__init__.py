"""veribattery: verify battery-powered robot missions with an in-repo PRISM DTMC model checker."""

__version__ = "0.1.0"
