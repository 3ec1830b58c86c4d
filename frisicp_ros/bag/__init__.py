"""The offline bag mode without ROS: reading bags (rosbags), pairing their clouds, running the
registrations (in parallel processes) and writing JSONL and result bags.
"""
