"""Tests of the documentation: the MkDocs site and the README."""
