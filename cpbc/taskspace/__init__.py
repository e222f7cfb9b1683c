"""Task-space goals (TASKSPACE §3): a frame's goal pose, the task gains from the arm's
task-space inertia at the posture, the task potential and damping a law takes, and the IK
preflight that predicts where the law will rest."""
