"""How a fleet is planned: the stages (whole fleet, prioritized batches, dodges, routes), goal
assignment, horizons, sequences, landings and replans."""
