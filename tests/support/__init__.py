"""Helpers shared by the tests (fakes, factories); never a test module."""
