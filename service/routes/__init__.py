"""HTTP routes of the service: one router per resource, thin (the work is in the service modules)."""
