"""Reporting: figures and tables drawn only from stored results."""
