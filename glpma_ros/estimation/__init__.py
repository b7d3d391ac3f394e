"""From leg lengths to the published pose: :mod:`.estimator` (the warm/cold solve of each input),
:mod:`.redundancy` (redundant legs' consistency test), :mod:`.covariance` (pose covariance),
:mod:`.velocity` (the platform's twist)."""
