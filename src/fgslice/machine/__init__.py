"""Machines: dialects (state-change commands), the G-code writer, printer profiles."""
