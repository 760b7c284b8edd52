"""Scenario generators: the paper's cases and the benchmark families."""
