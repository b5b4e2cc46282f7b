"""(being moved)"""
