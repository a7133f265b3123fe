"""The --exact checker: PCTL in rational arithmetic."""
