"""Luxonis OAK cameras through depthai 3.x, in a supervised child process."""
