"""vega_plant: truth-side vehicle model library (plain Python) and its ROS 2 nodes."""
