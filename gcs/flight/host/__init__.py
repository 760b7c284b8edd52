"""Where flights run apart from their caller: the vehicle thread, the vehicle process, and the
handle another loop drives a flight through."""
