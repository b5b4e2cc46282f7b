"""As a plant runs it: the onboarding page at real time and the soak test."""
