"""Shows designed in other tools, brought into fleetplan: a Skybrush compiled show (`.skyc`,
`gcs.show.skyc_reader`) or Skybrush's per-drone CSV (`gcs.show.csv_reader`) read as design
tracks (`gcs.show.tracks`), whose hold points become a formation sequence with its colours
(`gcs.show.to_sequence`) for the planner to plan the transitions between them.

Pure functions of files to JSON documents: no vehicles, no service; the CLI (`fleetplan
import`, `fleetplan report`) and the service's show routes (`gcs.api.routes.shows`) call them.
"""
