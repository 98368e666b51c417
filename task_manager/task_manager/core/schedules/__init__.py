"""Schedules: what one is and when it fires, every schedule and which are due, a request
checked, and the store on disk."""
