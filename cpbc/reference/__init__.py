"""Moving references for a frame (TASKSPACE §2.4, §3): paths with their nominal timing, the
moving target the laws' springs read, the posture path and its admissibility, the explicit
reference governor on the path parameter, and the controller wrapper that runs them."""
